"""Other co-simulation masters running one system of FMUs: libcosim (libcosimpy), Ecos (ecospy)
and fmpy's own `simulate_fmu`, each returning the recorded output on the communication grid.

A system here is plain data (`FmuSystem`): FMU files by instance name, connections between
"instance.variable" names, start values, the step and the end time. Every master gets exactly
that and nothing else; an input no connection feeds keeps its FMU start value (the feathers'
flow speed: still water). Each runner loads the FMUs from their files, so its wall time
includes what loading costs, as featherstar's does.

`available()` says which masters import here and, for each that does not, why (the exception
text): a missing peer is a measured absence, not a silent gap.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

import numpy as np


@dataclass(frozen=True)
class FmuSystem:
    """FMUs by instance name, connections ("src.out", "dst.in"), start values ("inst.param": value)."""

    fmus: Mapping[str, Path]
    connections: tuple[tuple[str, str], ...]
    start_values: Mapping[str, float] = field(default_factory=dict)
    step_s: float = 1e-3
    stop_s: float = 1.0

    @property
    def steps(self) -> int:
        return int(round(self.stop_s / self.step_s))


def _split(name: str) -> tuple[str, str]:
    instance, _, variable = name.partition(".")
    return instance, variable


def available() -> dict[str, str | None]:
    """Master name -> None when it imports, else the reason it does not (one line)."""
    out: dict[str, str | None] = {}
    for master, module in (("libcosim", "libcosimpy.CosimExecution"), ("ecos", "ecospy"), ("fmpy", "fmpy")):
        try:
            importlib.import_module(module)
            out[master] = None
        except Exception as exc:  # an ImportError, or an OSError from a missing shared library
            out[master] = f"{module} does not import: {type(exc).__name__}: {str(exc).splitlines()[0]}"
    return out


def run_libcosim(system: FmuSystem, signal: str) -> np.ndarray:
    """libcosim's fixed-step master (all slaves step from the same start values, then transfer).
    Returns `signal` at t = 0, h, ..., stop (libcosim counts time in integer nanoseconds)."""
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.ERROR)
    step_ns = int(round(system.step_s * 1e9))
    execution = CosimExecution.from_step_size(step_ns)
    index: dict[str, int] = {}
    refs: dict[str, dict[str, int]] = {}
    for name, path in system.fmus.items():
        index[name] = execution.add_local_slave(CosimLocalSlave(fmu_path=str(path), instance_name=name))
        if index[name] < 0:
            raise RuntimeError(f"libcosim could not load {path}")
        refs[name] = {v.name.decode(): v.reference for v in execution.slave_variables(index[name])}
    for source, sink in system.connections:
        (a, x), (b, y) = _split(source), _split(sink)
        if execution.connect_real_variables(index[a], refs[a][x], index[b], refs[b][y]) < 0:
            raise RuntimeError(f"libcosim refused the connection {source} -> {sink}")
    for key, value in system.start_values.items():
        a, x = _split(key)
        if not execution.real_initial_value(index[a], refs[a][x], float(value)):
            raise RuntimeError(f"libcosim refused the start value {key} = {value}")
    # The time series holds t = 0 .. stop - h (libcosim 0.11 leaves out the last step's sample);
    # the last-value observer gives the value at stop.
    observer, last = CosimObserver.create_time_series(buffer_size=system.steps + 2), CosimObserver.create_last_value()
    execution.add_observer(observer)
    execution.add_observer(last)
    a, x = _split(signal)
    observer.start_time_series(index[a], refs[a][x], CosimVariableType.REAL)
    if not execution.simulate_until(system.steps * step_ns):
        raise RuntimeError("libcosim's simulate_until failed")
    times_ns, _, values = observer.time_series_real_samples(index[a], refs[a][x], 0, system.steps + 1)
    if len(values) != system.steps or not np.array_equal(np.asarray(times_ns), np.arange(system.steps) * step_ns):
        raise RuntimeError(f"libcosim recorded {len(values)} samples of {signal}, not {system.steps} on the grid")
    return np.append(np.asarray(values, dtype=float), last.last_real_values(index[a], [refs[a][x]])[0])


def run_ecos(system: FmuSystem, signal: str) -> np.ndarray:
    """Ecos (Vico's engine) with its fixed-step algorithm; `signal` read after every step."""
    from ecospy import EcosSimulation, EcosSimulationStructure
    from ecospy.lib import EcosLib

    EcosLib.set_log_level("warn")
    key = signal.replace(".", "::", 1)
    with EcosSimulationStructure() as structure:
        for name, path in system.fmus.items():
            structure.add_model(name, str(path))
        for source, sink in system.connections:
            structure.make_real_connection(source.replace(".", "::", 1), sink.replace(".", "::", 1))
        structure.add_parameter_set("bench", {k.replace(".", "::", 1): float(v) for k, v in system.start_values.items()})
        with EcosSimulation(structure=structure, step_size=system.step_s) as sim:
            if not sim.init(parameter_set="bench"):
                raise RuntimeError(f"Ecos could not initialize: {EcosLib.get_last_error()}")
            values = np.empty(system.steps + 1)
            values[0] = sim.get_real(key)
            for k in range(1, system.steps + 1):
                sim.step()
                values[k] = sim.get_real(key)
            sim.terminate()
    return values


def run_fmpy(system: FmuSystem, signal: str, inputs: Callable[[np.ndarray], Mapping[str, np.ndarray]],
             rtol: float = 1e-6) -> np.ndarray:
    """fmpy.simulate_fmu (Co-Simulation) of a one-FMU system; `inputs(grid)` gives its input
    signals sampled on the communication grid (fmpy sets them at each step's start)."""
    import fmpy

    if len(system.fmus) != 1:
        raise ValueError("fmpy.simulate_fmu runs one FMU; this system has "
                         f"{len(system.fmus)} ({', '.join(system.fmus)})")
    (name, path), = system.fmus.items()
    grid = system.step_s * np.arange(system.steps + 1)
    signals = inputs(grid)
    table = np.zeros(len(grid), dtype=[("time", np.float64)] + [(n, np.float64) for n in signals])
    table["time"] = grid
    for column, values in signals.items():
        table[column] = values
    result = fmpy.simulate_fmu(str(path), fmi_type="CoSimulation", start_time=0.0, stop_time=float(grid[-1]),
                               step_size=system.step_s, output_interval=system.step_s,
                               input=table if signals else None,
                               start_values={_split(k)[1]: v for k, v in system.start_values.items()},
                               output=[_split(signal)[1]], relative_tolerance=rtol)
    values = np.asarray(result[_split(signal)[1]], dtype=float)
    if len(values) != len(grid):
        raise RuntimeError(f"fmpy returned {len(values)} samples of {signal}, not {len(grid)}")
    return values


RUNNERS: dict[str, Callable[..., np.ndarray]] = {"libcosim": run_libcosim, "ecos": run_ecos, "fmpy": run_fmpy}
