"""Weak coupling: Jacobi or Gauss-Seidel macro steps with inputs held.

Units are stepped as co-simulation units over macro steps with inputs held (zero-order hold;
FMI 3.0 co-simulation has no input derivatives). Jacobi steps every unit from the values at t;
Gauss–Seidel steps units in signal-flow order, each from the newest values. After a macro step
the schedule makes inputs and outputs consistent at the new communication point (solving
algebraic loops there). ME-only units are stepped by their own CVODE (MeStepper). With
`adaptive = true` the macro step is controlled by an error estimate of the zero-order hold (half
the change of each input over the step, relative to its running magnitude, against
`macro_rtol`): a step above tolerance is rolled back (saved states) and repeated smaller.

`WeakCoupling` is the strategy the Simulator (featherstar.cosim.coupling.simulator) drives. A real-time run passes
a `pace(t, h)` callable (featherstar.cosim.coupling.pacing) that waits for each step's wall-clock time.
"""
from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ..errors import StepError
from ..framework.units import Unit
from ..scene.data import PortRef
from ._cvode import CVodeError
from .context import Context, Recording
from .schedule import setter_op, topo_schedule, watched_out_nodes
from .ode_group import OdeGroup
from .system import System


class MeStepper:
    """Steps one Model Exchange unit as a co-simulation unit with its own CVODE (inputs held).

    CVODE keeps its step size and order history from one macro step to the next, so a unit
    whose inputs did not change is integrated exactly as strong coupling would (same rtol, same
    error control); it restarts only where the right-hand side jumps: at changed inputs, at
    events and after a rollback. Discrete inputs are taken in event mode at the step's start;
    time events inside the step are located exactly (featherstar.cosim.coupling.ode_group.OdeGroup.integrate)."""

    def __init__(self, system: System, context: Context, unit: Unit, t0: float, method: str, rtol: float,
                 atol: float) -> None:
        self.unit = unit
        self.group = OdeGroup(system, context, [unit], [], t0, method=method, rtol=rtol, atol=atol)
        self._n_in = len(unit.input_names)
        self._held: list[float] | None = None  # the inputs CVODE's history was computed with

    def do_step(self, t: float, h: float) -> None:
        g = self.group
        held = list(self.unit.inbuf)[: self._n_in]
        if self.unit.discrete_inputs_changed():
            g.handle_event(t)  # event mode: take the discrete inputs (re-initialises CVODE)
        elif held != self._held or abs(g.cv.t - t) > 1e-12 * max(1.0, abs(t)):
            g.cv.reinit(t)  # the inputs jumped at the communication point
        self._held = held
        try:
            _, terminate = g.integrate(t + h, t + h, np.empty(0), 0, lambda _t: None)
        except CVodeError as exc:
            raise g.diagnose(exc) from None
        if terminate and self.unit.terminated_at_s is None:
            self.unit.terminated_at_s = g.cv.t
        self.unit.set_time(t + h)
        if g.stateful:
            self.unit.set_states(g.cv.y_address)

    def next_time_event(self) -> float | None:
        return self.unit.next_time_event()

    def get_state(self) -> Any:
        return (self.group.cv.t, list(self.group.cv.y), self.unit.get_state())

    def set_state(self, state: Any) -> None:
        t, y, inner = state
        self.unit.set_state(inner)
        for i, v in enumerate(y):
            self.group.cv.y[i] = v
        self.group.cv.t = t
        self._held = None  # CVODE's history belongs to the rejected step: restart
        if self.group.stateful:
            self.unit.set_time(t)
            self.unit.set_states(self.group.cv.y_address)

    def free_state(self, state: Any) -> None:
        self.unit.free_state(state[2])


def next_time_event(steppers: Any) -> float:
    """The earliest time event any stepped unit announced (ME FMUs: nextEventTime)."""
    times = [s.next_time_event() for s in steppers]
    return min((t for t in times if t is not None), default=math.inf)


def continuous_inputs(system: System, unit: Unit) -> list[int]:
    """The inputs whose change over a macro step measures the zero-order hold's error: those
    driven by continuous real outputs (a discrete or integer signal jumps; holding it is exact)."""
    out = []
    for i, name in enumerate(unit.input_names):
        src = system.plan.driver(PortRef(unit.name, name))
        port = system.plan.blocks[src.block].outputs[src.port]
        if not port.discrete and port.type in ("Float64", "Float32"):
            out.append(i)
    return out


class WeakCoupling:
    """Jacobi or Gauss–Seidel macro steps (see the module docstring); the Simulator's strategy for
    master.coupling = jacobi | gauss-seidel."""

    def __init__(self, system: System, context: Context, recording: Recording,
                 pace: Callable[[float, float], None] | None = None) -> None:
        self.system, self.context, self.recording, self.pace = system, context, recording, pace
        self.m = system.master
        self.units = list(system.units.values())
        self.steppers: dict[str, Any] = {}
        self.takes_discrete: list[MeStepper] = []
        self.check = system.output_checker(self.units)
        self.t = 0.0
        self.n_steps = self.n_rejected = 0
        # (the units that asked to terminate, the communication point where the run ended)
        self.ended: tuple[str, float] | None = None

    def initialize(self, t0: float, t_end: float) -> None:
        system, context, m, units = self.system, self.context, self.m, self.units
        for u in units:
            if u.memoryless:
                continue
            self.steppers[u.name] = (MeStepper(system, context, u, t0, m.method, m.rtol, m.atol)
                                     if u.continuous else u)
        self.takes_discrete = [s for s in self.steppers.values()
                               if isinstance(s, MeStepper) and s.unit.has_discrete_inputs]
        self.sched = topo_schedule(system, context, units, watched_out_nodes(system, self.recording))
        # Gauss–Seidel order: signal flow, sources first
        self.flow = system.flow_order(units)
        self.per_unit_set = {u.name: setter_op(system, u, list(range(len(u.input_names))), system.input_sources(u))
                             for u in units if u.input_names}
        self.per_unit_get = {u.name: u.output_getter(list(range(len(u.output_names))))
                             for u in units if u.output_names}
        self.stepped = [u for u in self.flow if u.name in self.steppers]
        self.memoryless = [u for u in units if u.memoryless]
        self.t_end = t_end
        self.consistent(t0)
        self.check(t0)
        self.recording.record(t0)
        self.recording.check_rows()
        self.h = m.step_s
        self.t = t0
        self.scale = {u.name: [abs(u.inbuf[i]) for i in range(len(u.input_names))] for u in self.stepped}
        self.estimated = {u.name: continuous_inputs(system, u) for u in self.stepped}
        self._check_terminated(t0)

    def _check_terminated(self, t: float) -> None:
        """A unit that asked to terminate ends the run at this communication point, normally."""
        asked = [u.name for u in self.units if u.terminated_at_s is not None]
        if asked:
            self.ended = (", ".join(asked), t)

    def consistent(self, t: float) -> None:
        """Every input and output at t; ME units take changed discrete inputs in event mode there
        (and the others see what that changes), so recorded values are those after the event."""
        for _ in range(100):
            self.context.t = t
            for u in self.memoryless:
                u.set_time(t)
            for op in self.sched:
                op()
            pending = [s for s in self.takes_discrete if s.unit.discrete_inputs_changed()]
            if not pending:
                return
            for s in pending:
                s.group.handle_event(t)
        raise StepError(",".join(s.unit.name for s in pending), t, "discrete inputs kept changing in 100 event "
                        "iterations at one communication point", function="event iteration",
                        cause="a loop of discrete signals without a delay")

    def input_changed(self, t: float) -> None:
        """An input written from outside: the communication point's values follow it."""
        self.consistent(t)

    def advance_to(self, t_target: float) -> float:
        """Macro steps until t_target; the last one is shortened to land on it unless it is within
        rounding of the macro grid (so chunks on the grid take the same steps as one call)."""
        m, context, recording = self.m, self.context, self.recording
        steppers, flow, stepped = self.steppers, self.flow, self.stepped
        per_unit_set, per_unit_get = self.per_unit_set, self.per_unit_get
        t_end = self.t_end
        t, h = self.t, self.h
        eps = 1e-12 * max(1.0, abs(t_end))
        gs = m.coupling == "gauss-seidel"
        while t < t_target - eps and self.ended is None:
            if self.pace is not None:
                self.pace(t, h)
            h_try = min(h, t_end - t)
            if t + h_try > t_end - 1e-9 * h_try:
                h_try = t_end - t
            if t + h_try > t_target + 1e-9 * h_try:
                h_try = t_target - t
            t_event = next_time_event(steppers.values())
            if t + eps < t_event < t + h_try - eps:
                h_try = t_event - t  # a communication point at the event: its effect passes on at once
            # a step that ends at a time event is taken Jacobi-style: Gauss-Seidel would hand the
            # values after the event to the units downstream for the whole step before it
            gs_step = gs and abs(t + h_try - t_event) > eps
            saved = {n: s.get_state() for n, s in steppers.items()} if m.adaptive else None
            used: dict[str, list[float]] = {}
            try:
                if gs_step:
                    for u in flow:
                        if u.memoryless:
                            context.t = t + h_try
                            u.set_time(t + h_try)
                            if u.name in per_unit_set:
                                per_unit_set[u.name]()
                            if u.name in per_unit_get:
                                per_unit_get[u.name]()
                            continue
                        context.t = t
                        if u.name in per_unit_set:
                            per_unit_set[u.name]()
                        used[u.name] = list(u.inbuf)[: len(u.input_names)]
                        steppers[u.name].do_step(t, h_try)
                        if u.name in per_unit_get:
                            per_unit_get[u.name]()
                else:
                    for u in stepped:
                        used[u.name] = list(u.inbuf)[: len(u.input_names)]
                    context.t = t
                    for u in stepped:
                        steppers[u.name].do_step(t, h_try)
                self.consistent(t + h_try)
            except StepError as exc:
                if m.adaptive and saved is not None and h_try > m.min_step_s and "discard" in str(exc):
                    for n, s in steppers.items():
                        s.set_state(saved[n])
                    self.consistent(t)
                    h = h_try * 0.25
                    self.n_rejected += 1
                    continue
                raise
            if m.adaptive:
                err = 0.0
                for u in stepped:
                    sc = self.scale[u.name]
                    for i in self.estimated[u.name]:
                        old, new = used[u.name][i], u.inbuf[i]
                        sc[i] = max(sc[i], abs(new))
                        e = 0.5 * abs(new - old) / (m.atol + m.macro_rtol * sc[i])
                        if e > err:
                            err = e
                if err > 1.0 and h_try > m.min_step_s * 1.0001:
                    for n, s in steppers.items():
                        s.set_state(saved[n])
                        s.free_state(saved[n])
                    self.consistent(t)
                    h = max(m.min_step_s, h_try * max(0.2, 0.9 / err))
                    self.n_rejected += 1
                    continue
                for n, s in steppers.items():
                    s.free_state(saved[n])
                h = min(m.max_macro_step_s, h_try * min(2.0, 0.9 / max(err, 1e-12)))
            t = t + h_try
            self.t, self.h = t, h
            self.n_steps += 1
            self.check(t)
            recording.record(t)
            if self.n_steps % 256 == 0:
                recording.tick(t)
            self._check_terminated(t)
        context.stats.update({"macro_steps": self.n_steps, "rejected_steps": self.n_rejected})
        recording.check_rows()
        return t

    def get_state(self) -> tuple:
        """Every stepped unit's saved state and the step controller's (t, h, input scales)."""
        states = {n: s.get_state() for n, s in self.steppers.items()}
        return self.t, self.h, {k: list(v) for k, v in self.scale.items()}, states

    def set_state(self, state: tuple) -> None:
        t, h, scale, states = state
        for n, s in self.steppers.items():
            s.set_state(states[n])
        self.t, self.h = t, h
        self.scale = {k: list(v) for k, v in scale.items()}
        self.ended = None   # restored units forget a later request to terminate
        self.consistent(t)

    def free_state(self, state: tuple) -> None:
        for n, s in self.steppers.items():
            s.free_state(state[3][n])

    def close(self) -> None:
        for s in self.steppers.values():
            if isinstance(s, MeStepper):
                s.group.cv.free()
