"""A scene's [master] and [metrics] tables: every key declared with its type, default, range,
unit and meaning (featherstar.cosim.scene.settings); `check()` lists what is out of range.

Tolerance ranges are what the solvers can honour and what keeps a result a result: CVODE cannot
meet a relative tolerance much below 1e-12 in double precision, and on the test bed (plain
feather, 4 periods) an absolute tolerance of 1e-3 moves the mean thrust by 2 %, 1e-2 by 14 % and
1 by 17x, while 1e-4 moves it by 0.04 % (`atol` bounds the error of every state, in its own unit:
the thrust is a few mN). Time steps and grids have no upper bound of their own: what a coarse
one costs depends on the stroke and the run (the step guards, featherstar.cosim.scene.guards, and
the metric window's sample count, featherstar.cosim.scene.preflight, judge it); the emulated
plant (featherstar.hil.fmu_plant) records once per month on purpose.
"""
from __future__ import annotations

from dataclasses import dataclass

from .settings import setting, setting_problems

COUPLINGS = ("strong", "mixed", "jacobi", "gauss-seidel", "auto")
METHODS = ("bdf", "adams", "adams-fixedpoint")


@dataclass(frozen=True)
class MasterSpec:
    """How the master runs a scene. Each key's type, range and unit: its `setting` below.

    coupling           strong: ME FMUs (and memoryless Python blocks) integrated together as one
                       ODE by CVODE; jacobi / gauss-seidel: blocks stepped as co-simulation
                       units, inputs held (zero-order hold) over each macro step; mixed: the
                       continuous blocks as one ODE, the blocks that can only step (CS-only
                       FMUs, Python blocks with state) stepped every step_s around it; auto:
                       strong, mixed or gauss-seidel, whichever the scene's blocks allow.
    method             CVODE method for strong coupling and for ME-only FMUs in weak coupling:
                       bdf (stiff) or adams (non-stiff).
    rtol, atol         tolerances of every error-controlled integrator (CVODE here; passed to
                       CS FMUs as their tolerance), and of the adaptive macro-step control.
    step_s             weak coupling: the macro (communication) step; the initial one if adaptive.
    max_step_s         strong coupling: largest solver step (0 = no limit).
    adaptive           weak coupling: control the macro step from an error estimate, rejecting
                       and rolling back steps whose estimate exceeds the tolerance.
    macro_rtol         adaptive macro step: tolerated zero-order-hold error, relative to each
                       coupled input's running magnitude (half its change over a step).
    min_step_s, max_macro_step_s   bounds of the adaptive macro step.
    t_end_s            run length; 0 = `periods` periods of the scene's stroke.
    periods            run length in stroke periods when t_end_s = 0.
    output_interval_s  recording grid (strong coupling; weak records every communication point).
    dedup              integrate identical blocks driven by identical signals once.
    loop_tol, loop_max_iter   algebraic-loop iteration (Newton with a finite-difference Jacobian).
    algebraic_loops    iterate | error: whether algebraic loops may be solved by iteration.
    backend            fmu: model blocks run as exported FMUs through fmpy; casadi: in-process
                       (no export; for development and for FMU-free checks).
    realtime           weak coupling: pace macro steps on the wall clock (hardware in the loop);
                       steps that start late are counted as deadline misses.
    check_steps        refuse a recording grid or fixed macro step too coarse for the stroke, and a
                       macro step too long for a feedback loop (featherstar.cosim.scene.guards); false only to study
                       the sampling or coupling error itself.
    passive_energy_factor  stop when a passive block (a feather) gains more than this multiple of
                       the work its ports put in (featherstar.cosim.scene.guards); 0 = no check.
    compiled_rhs       strong coupling: run the right-hand side as compiled C calls
                       (featherstar.cosim.coupling.compiled_rhs; needs gcc); false: the Python path.
    start_at_rest      strong coupling: start from the state in which every continuous state's
                       derivative is zero for the inputs at the start (a bench left alone:
                       featherstar.cosim.coupling.rest), not from the models' start values.
    """

    coupling: str = setting("strong", "strong: one ODE by CVODE; jacobi / gauss-seidel: macro steps; "
                            "mixed: one ODE with stepped blocks around it; auto: what the blocks allow",
                            choices=COUPLINGS)
    method: str = setting("bdf", "CVODE method: bdf (stiff) or adams (non-stiff)", choices=METHODS)
    rtol: float = setting(1e-6, "relative tolerance of every error-controlled integrator", "1",
                          lo=1e-12, hi=1e-2)
    atol: float = setting(1e-8, "absolute tolerance of every integrator (per state, its unit)", "1",
                          lo=1e-14, hi=1e-4)
    step_s: float = setting(1e-3, "weak coupling: the macro (communication) step, the first if adaptive",
                            "s", lo=1e-7)
    max_step_s: float = setting(0.0, "strong coupling: largest solver step", "s", lo=1e-9,
                                zero_means="no limit")
    adaptive: bool = setting(False, "weak coupling: control the macro step from an error estimate")
    macro_rtol: float = setting(1e-3, "adaptive macro step: tolerated zero-order-hold error, relative",
                                "1", lo=1e-8, hi=0.5)
    min_step_s: float = setting(1e-7, "smallest adaptive macro step", "s", lo=1e-12)
    max_macro_step_s: float = setting(0.05, "largest adaptive macro step", "s", lo=1e-9)
    t_end_s: float = setting(0.0, "run length", "s", lo=0.0, zero_means="`periods` stroke periods")
    periods: float = setting(6.0, "run length in stroke periods when t_end_s = 0", lo=0.0)
    output_interval_s: float = setting(1e-3, "recording grid (strong coupling)", "s", lo=1e-9)
    dedup: bool = setting(True, "integrate identical blocks driven by identical signals once")
    loop_tol: float = setting(1e-10, "algebraic-loop iteration: tolerance", "1", lo=1e-15, hi=1e-2)
    loop_max_iter: int = setting(50, "algebraic-loop iteration: most iterations", lo=1, hi=10_000)
    algebraic_loops: str = setting("iterate", "whether algebraic loops may be solved by iteration",
                                   choices=("iterate", "error"))
    backend: str = setting("fmu", "fmu: models as exported FMUs; casadi: in-process (no export)",
                           choices=("fmu", "casadi"))
    realtime: bool = setting(False, "weak coupling: pace macro steps on the wall clock")
    check_steps: bool = setting(True, "refuse a grid or macro step too coarse for the stroke or a loop")
    passive_energy_factor: float = setting(2.0, "stop when a passive block gains this multiple of "
                                           "the work put in", lo=0.0, zero_means="no check")
    compiled_rhs: bool = setting(True, "strong coupling: right-hand side as compiled C calls (gcc)")
    start_at_rest: bool = setting(False, "strong coupling: start from the state at rest")

    def check(self) -> list[str]:
        problems = setting_problems(self, "master")
        if self.realtime and self.coupling == "strong":
            problems.append("master.realtime needs communication steps (mixed, jacobi or gauss-seidel): "
                            "hardware cannot be integrated inside one ODE")
        if self.start_at_rest and self.coupling != "strong":
            problems.append("master.start_at_rest needs master.coupling = strong: the state at rest is solved "
                            "on the coupled ODE")
        if self.t_end_s == 0 and self.periods == 0:
            problems.append("master: set t_end_s or periods")
        if self.adaptive and self.min_step_s > self.max_macro_step_s:
            problems.append(f"master.min_step_s = {self.min_step_s:g} is above master.max_macro_step_s = "
                            f"{self.max_macro_step_s:g}")
        return problems


@dataclass(frozen=True)
class MetricsSpec:
    """Which signals the paper's metrics read. Empty = metric not computed.

    thrust          thrust signal (N) for mean thrust (Eq. 2) and thrust ratio TR (Eq. 3)
    angle           root angle (rad), drawn with the thrust in the figure
    speed           body speed (m/s) for the robot's mean speed
    position        body position (m); mean speed = displacement / window when given
    settle_periods  metrics use whole periods after this many periods of transient
    period_s        metric period; 0 = the period of the scene's stroke controller
    """

    thrust: str = setting("", "thrust signal (N): mean thrust (Eq. 2) and thrust ratio TR (Eq. 3)",
                          signal=True)
    angle: str = setting("", "root angle signal (rad), drawn with the thrust", signal=True)
    speed: str = setting("", "body speed signal (m/s): the robot's mean speed", signal=True)
    position: str = setting("", "body position signal (m): mean speed = displacement / window",
                            signal=True)
    settle_periods: float = setting(3.0, "periods of transient before the metric window", lo=0.0)
    period_s: float = setting(0.0, "metric period", "s", lo=1e-6, hi=1e6,
                              zero_means="the scene's stroke period")

    def signals(self) -> list[str]:
        return [s for s in (self.thrust, self.angle, self.speed, self.position) if s]

    def check(self) -> list[str]:
        return setting_problems(self, "metrics")
