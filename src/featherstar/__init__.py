"""featherstar: co-simulation of soft robotic swimmers. The command line is `featherstar.app`;
the library is in fmu_src (models as FMUs), cosim (scenes and the Simulator), optimizer (stroke
optimization, sweeps, the paper) and hil (hardware in the loop); docs/architecture.md."""
