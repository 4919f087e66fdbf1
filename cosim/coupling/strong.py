"""Strong coupling: every continuous unit integrated together as one ODE by CVODE.

Each right-hand-side evaluation sets time and states on every unit and then walks the schedule
(featherstar.cosim.coupling.schedule): inputs copied from the outputs that drive them, outputs evaluated in
dependency order, algebraic loops solved by Newton iteration. Memoryless blocks (the stroke
controller) are evaluated at the solver's own instants, so inputs are exact between output
times. Outputs are recorded on the output grid from CVODE's dense output. State and time events
of generic ME FMUs are handled (root finding, event iteration, re-initialisation).

`StrongCoupling` is the strategy the Simulator (featherstar.cosim.coupling.simulator) drives: `initialize()`, then
`advance_to(t)` any number of times. Without events CVODE's stop time is the run's end whatever
the chunks, so stepping in chunks gives the same numbers as one call to the end.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ._cvode import N_VGET_ARRAY_POINTER_ADDRESS, CVodeError
from .compiled_rhs import compile_rhs
from .context import Context, Recording
from .ode_group import OdeGroup
from .rest import solve_rest
from .schedule import schedule_steps, topo_schedule, watched_out_nodes
from .system import System


class StrongCoupling:
    """All continuous units as one ODE (see the module docstring); the Simulator's strategy for
    master.coupling = strong."""

    def __init__(self, system: System, context: Context, recording: Recording) -> None:
        self.system, self.context, self.recording = system, context, recording
        self.units = list(system.units.values())
        self.group: OdeGroup | None = None
        self.out_times = np.empty(0)
        self.k = 0
        self.terminated = False
        self.check = system.output_checker(self.units)
        self.last_output_t = -math.inf

    def initialize(self, t0: float, t_end: float) -> None:
        """Build the schedules and the solver over the started units; record the start."""
        system, context, m = self.system, self.context, self.system.master
        watched = watched_out_nodes(system, self.recording)
        rhs_steps = schedule_steps(system, context, self.units, set(), skip_static=True)
        rec_steps = schedule_steps(system, context, self.units, watched, skip_static=True)
        self.rec_ops = [step.run for step in rec_steps]
        self.init_ops = topo_schedule(system, context, self.units, watched)
        self.t_end = t_end
        group = self.group = OdeGroup(self.system, self.context, self.units, rhs_steps, t0, method=m.method,
                                      rtol=m.rtol, atol=m.atol, max_step=m.max_step_s, compiled=m.compiled_rhs)
        self.rhs_ops = group.ops
        # the output points as one C call too, when the right-hand side compiled
        self.record_program = None
        if context.stats.get("rhs") == "compiled":
            program = compile_rhs(context, group.timed, group.stateful, rec_steps, N_VGET_ARRAY_POINTER_ADDRESS)
            self.record_program = None if isinstance(program, str) else program
        self.consistent(t0)
        if m.start_at_rest:
            self._start_at_rest(t0)
        if group.discrete_units and group.discrete_inputs_pending(t0):
            # discrete inputs are taken in event mode before the start is recorded (values after the event)
            self.terminated = group.handle_event(t0)
        asked = [u.name for u in self.units if u.terminated_at_s is not None]   # at initialization
        if asked and not self.terminated:
            self.terminated, group.terminated_by = True, asked[0]
        n = int(math.floor((t_end - t0) / m.output_interval_s + 1e-9))
        out_times = t0 + m.output_interval_s * np.arange(n + 1)
        if out_times[-1] < t_end - 1e-12:
            out_times = np.append(out_times, t_end)
        self.out_times = out_times
        self.k = 0
        eps = 1e-12 * max(1.0, abs(t_end))
        while self.k < len(out_times) and out_times[self.k] <= t0 + eps:   # the start's outputs
            self._on_output(out_times[self.k], group.cv.y_address)
            self.k += 1
        if self.terminated:
            self.k = len(out_times)
        self.recording.check_rows()
        self.context.stats["states"] = 0 if group.dummy else group.n
        self.context.stats.setdefault("integrate_s", 0.0)

    def _start_at_rest(self, t0: float) -> None:
        """Replace the start values by the state at rest for the inputs at t0 (featherstar.cosim.coupling.rest)."""
        group, m = self.group, self.system.master
        if group.dummy:
            return
        names = [f"{u.name}.{s}" for u, _ in group.stateful
                 for s in (u.state_names() or [f"x{i}" for i in range(u.n_states)])]
        rest = solve_rest(group._rhs, t0, list(group.cv.y), m.rtol, m.atol, names)
        group.cv.reinit(t0, rest.y.tolist())
        self.consistent(t0)
        self.context.stats["start_at_rest"] = {"evaluations": rest.evaluations,
                                               "worst_rate_per_tolerance_1_s": rest.worst_rate_per_tolerance}

    def consistent(self, t: float) -> None:
        """Every unit at the solver's state at t, constants included (the start, or after an input
        was written from outside)."""
        group = self.group
        group.ops = self.init_ops
        group.set_point(t, group.cv.y_address)
        group.ops = self.rhs_ops

    def input_changed(self, t: float) -> None:
        """An input written from outside jumped at t: make everything consistent and restart the
        solver's history (a discontinuity)."""
        self.consistent(t)
        self.group.cv.reinit(t)

    def _on_output(self, t: float, y_address: int) -> None:
        """Every unit at (t, y) with the recorded outputs evaluated, checked, recorded."""
        if self.record_program is not None:
            self.record_program.point(t, y_address)
            self.context.t = t
        else:
            self.group.set_point(t, y_address)
            for op in self.rec_ops:
                op()
        self.check(t)
        self.recording.record(t)
        self.last_output_t = t
        if len(self.recording.rows) % 256 == 0:
            self.recording.tick(t)

    def advance_to(self, t_target: float) -> float:
        group = self.group
        if self.terminated:
            return group.cv.t
        t_wall = time.perf_counter()
        try:
            self.k, self.terminated = group.integrate(t_target, self.t_end, self.out_times, self.k, self._on_output)
            if self.terminated and self.last_output_t < group.cv.t:
                self._on_output(group.cv.t, group.cv.y_address)   # the run's last point is where it ended
        except CVodeError as exc:
            raise group.diagnose(exc) from None
        finally:
            self.context.stats.update(group.cv.stats())
            self.context.stats["integrate_s"] += time.perf_counter() - t_wall
        self.recording.check_rows()
        return group.cv.t

    @property
    def ended(self) -> tuple[str, float] | None:
        """(the unit that asked to terminate, the time the run ended there), or None."""
        return (self.group.terminated_by, self.group.cv.t) if self.terminated and self.group else None

    def get_state(self) -> tuple[float, list[float], list]:
        """The solver's state and every unit's (ME FMUs: their FMU state); restoring restarts
        CVODE's history at the saved time."""
        cv = self.group.cv
        return cv.t, list(cv.y), [u.get_state() for u in self.units], self.k

    def set_state(self, state: tuple) -> None:
        t, y, inner, k = state
        for u, s in zip(self.units, inner):
            u.set_state(s)
        cv = self.group.cv
        cv.reinit(t, y)
        self.k = k
        self.terminated = False
        self.group.terminated_by = ""
        self.consistent(t)

    def free_state(self, state: tuple) -> None:
        for u, s in zip(self.units, state[2]):
            u.free_state(s)

    def close(self) -> None:
        if self.group is not None:
            self.group.cv.free()
