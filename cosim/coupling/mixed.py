"""Mixed coupling: the continuous units as one ODE, the co-simulation units around it.

Every Model Exchange unit (and every memoryless block, evaluated at the solver's own instants) is
integrated together by one CVODE, exactly as the strong coupling does; units that can only step
(co-simulation-only FMUs, Python blocks with state such as hardware) are stepped at communication
points every `master.step_s`, their inputs held over the step and their outputs held for the
ODE (zero-order hold, Jacobi order: the ODE and the steppers both start from the values at t).
Only the signals that cross between the two sides carry a coupling error; a scene whose
co-simulation units sit outside its fast feedback loops keeps the strong coupling's accuracy.

While the held inputs do not change, CVODE keeps its history across communication points (the
same steps as strong coupling); it restarts where they jump. Outputs are recorded on the output
grid (`output_interval_s`), the co-simulation units' outputs as held. `MixedCoupling` is the
Simulator's strategy for master.coupling = mixed (also what `auto` picks when a scene has both
kinds); a real-time run is paced before every communication point.
"""
from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ..errors import StepError
from ._cvode import CVodeError
from .context import Context, Recording
from .schedule import schedule_steps, topo_schedule, watched_out_nodes
from .ode_group import OdeGroup
from .system import System
from .weak import next_time_event


class MixedCoupling:
    """One ODE for the continuous units, communication steps for the rest (module docstring)."""

    def __init__(self, system: System, context: Context, recording: Recording,
                 pace: Callable[[float, float], None] | None = None) -> None:
        self.system, self.context, self.recording, self.pace = system, context, recording, pace
        self.m = system.master
        self.units = list(system.units.values())
        self.inner = [u for u in self.units if u.continuous or u.memoryless]
        self.stepped = [u for u in self.units if not (u.continuous or u.memoryless)]
        self.check = system.output_checker(self.units)
        self.group: OdeGroup | None = None
        self.t = 0.0
        self.n_steps = 0
        # (the units that asked to terminate, the time the run ended there): a normal end
        self.ended: tuple[str, float] | None = None

    def initialize(self, t0: float, t_end: float) -> None:
        system, context, m = self.system, self.context, self.m
        held = {u.name for u in self.stepped}
        watched = watched_out_nodes(system, self.recording)
        rhs_steps = schedule_steps(system, context, self.inner, set(), skip_static=True, held=held)
        self.rec_ops = topo_schedule(system, context, self.inner, watched, skip_static=True, held=held)
        self.all_ops = topo_schedule(system, context, self.units, watched)
        self.group = OdeGroup(system, context, self.inner, rhs_steps, t0, method=m.method, rtol=m.rtol,
                              atol=m.atol, max_step=m.max_step_s, compiled=m.compiled_rhs)
        self.rhs_ops = self.group.ops
        # the inputs of the ODE's units driven from the stepped side: CVODE restarts when they jump
        self.held_inputs = [(u, i) for u in self.inner for i in range(len(u.input_names))
                            if system.source_of(u, i)[0] in held]
        self._held_values: list[float] | None = None
        self.t_end = t_end
        self.consistent(t0)
        n = int(math.floor((t_end - t0) / m.output_interval_s + 1e-9))
        out_times = t0 + m.output_interval_s * np.arange(n + 1)
        if out_times[-1] < t_end - 1e-12:
            out_times = np.append(out_times, t_end)
        self.out_times, self.k = out_times, 0
        self.t = t0
        self._record_due(t0)
        self.recording.check_rows()
        context.stats["states"] = 0 if self.group.dummy else self.group.n
        context.stats["mixed"] = {"ode": [u.name for u in self.inner], "stepped": sorted(held)}

    def consistent(self, t: float) -> None:
        """Every input and output at t, with the ODE's state at t (a communication point); ODE
        units with discrete inputs that changed take them in event mode there."""
        group = self.group
        self._everything_at(t)
        if group.discrete_units and group.discrete_inputs_pending(t):
            if group.handle_event(t):
                self.ended = (group.terminated_by, t)
            self._everything_at(t)

    def _everything_at(self, t: float) -> None:
        """Every unit's inputs and outputs at t, the stepped side's included, from the ODE's
        state (the right-hand side's schedule leaves the stepped side out)."""
        group = self.group
        group.ops = self.all_ops
        group.set_point(t, group.cv.y_address)
        group.ops = self.rhs_ops

    def input_changed(self, t: float) -> None:
        """An input written from outside jumped at t: consistent values, and CVODE restarts."""
        self.consistent(t)
        self.group.cv.reinit(t)

    def _record_due(self, t: float) -> None:
        """Record the output times up to t (a communication point, everything consistent there)."""
        eps = 1e-12 * max(1.0, abs(self.t_end))
        while self.k < len(self.out_times) and self.out_times[self.k] <= t + eps:
            self.check(t)
            self.recording.record(float(self.out_times[self.k]))
            self.k += 1

    def advance_to(self, t_target: float) -> float:
        group, m, t_end = self.group, self.m, self.t_end
        eps = 1e-12 * max(1.0, abs(t_end))
        t = self.t
        while t < t_target - eps and self.ended is None:
            h = min(m.step_s, t_end - t, t_target - t)
            if t + h > t_end - 1e-9 * h:
                h = t_end - t
            t_event = next_time_event(self.stepped)
            if t + eps < t_event < t + h - eps:
                h = t_event - t  # a communication point at the stepped side's event
            if self.pace is not None:
                self.pace(t, h)
            t_comm = t + h
            values = [u.inbuf[i] for u, i in self.held_inputs]
            if values != self._held_values or abs(group.cv.t - t) > eps:
                group.cv.reinit(t)
            self._held_values = values
            if self._integrate(t, t_comm):
                t = self.t = group.cv.t
                break
            self.context.t = t
            for u in self.stepped:
                u.do_step(t, h)
            self.consistent(t_comm)
            asked = [u.name for u in self.stepped if u.terminated_at_s is not None]
            if asked and self.ended is None:
                self.ended = (", ".join(asked), t_comm)
            t = self.t = t_comm
            self.n_steps += 1
            self._record_due(t)
            if self.n_steps % 256 == 0:
                self.recording.tick(t)
        self.context.stats.update({"macro_steps": self.n_steps})
        self.recording.check_rows()
        return t

    def _integrate(self, t: float, t_comm: float) -> bool:
        """The ODE from t to t_comm with the stepped side's outputs held; output times inside the
        step are recorded from CVODE's dense output, the one at t_comm after the communication.
        Returns whether a unit of the ODE asked to terminate (the run then ends there, its last
        point recorded)."""
        group = self.group
        eps = 1e-12 * max(1.0, abs(self.t_end))

        def on_output(t_out: float, y_address: int) -> None:
            if t_out >= t_comm - eps:
                return   # recorded after the stepped side has stepped (_record_due)
            group.set_point(t_out, y_address)
            for op in self.rec_ops:
                op()
            self.check(t_out)
            self.recording.record(t_out)
            recorded.append(t_out)

        recorded: list[float] = []
        inside = self.out_times[(self.out_times > t + eps) & (self.out_times < t_comm - eps)]
        try:
            k, terminated = group.integrate(t_comm, t_comm, inside, 0, on_output)
        except CVodeError as exc:
            raise group.diagnose(exc) from None
        self.k += k
        self.context.stats.update(group.cv.stats())
        if terminated:
            t_stop = group.cv.t
            self.ended = (group.terminated_by, t_stop)
            self._everything_at(t_stop)
            if not recorded or recorded[-1] < t_stop - eps:   # the run's last point is where it ended
                self.check(t_stop)
                self.recording.record(t_stop)
        return terminated

    def get_state(self) -> Any:
        raise StepError("master", self.t, "the mixed coupling cannot save and restore its state",
                        cause="use master.coupling = strong or a weak coupling to roll back")

    def set_state(self, state: Any) -> None:
        self.get_state()

    def free_state(self, state: Any) -> None:
        self.get_state()

    def close(self) -> None:
        if self.group is not None:
            self.group.cv.free()
