"""Weak coupling: Jacobi or Gauss-Seidel macro steps with inputs held (cosim.master)."""
from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ._cvode import CVodeError
from .errors import StepError
from .master import RunContext, check_all_rows, output_checker, watched_out_nodes
from .scene import PortRef
from .schedule import flow_order, input_sources, setter_op, topo_schedule
from .strong import OdeGroup
from .units import Unit


class MeStepper:
    """Steps one Model Exchange unit as a co-simulation unit with its own CVODE (inputs held).

    CVODE keeps its step size and order history from one macro step to the next, so a unit
    whose inputs did not change is integrated exactly as strong coupling would (same rtol, same
    error control); it restarts only where the right-hand side jumps: at changed inputs, at
    events and after a rollback. Discrete inputs are taken in event mode at the step's start;
    time events inside the step are located exactly (cosim.strong.OdeGroup.integrate)."""

    def __init__(self, ctx: RunContext, unit: Unit, t0: float, method: str, rtol: float, atol: float) -> None:
        self.unit = unit
        self.group = OdeGroup(ctx, [unit], [], t0, method=method, rtol=rtol, atol=atol)
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
            g.check_not_terminated(g.integrate(t + h, np.empty(0), lambda _t: None))
        except CVodeError as exc:
            raise g.diagnose(exc) from None
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


def continuous_inputs(ctx: RunContext, unit: Unit) -> list[int]:
    """The inputs whose change over a macro step measures the zero-order hold's error: those
    driven by continuous real outputs (a discrete or integer signal jumps; holding it is exact)."""
    out = []
    for i, name in enumerate(unit.input_names):
        src = ctx.plan.driver(PortRef(unit.name, name))
        port = ctx.plan.blocks[src.block].outputs[src.port]
        if not port.discrete and port.type in ("Float64", "Float32"):
            out.append(i)
    return out


def run_weak(ctx: RunContext, t0: float, t_end: float) -> None:
    plan = ctx.plan
    m = plan.scene.master
    units = list(ctx.units.values())
    steppers: dict[str, Any] = {}
    for u in units:
        if u.memoryless:
            continue
        steppers[u.name] = MeStepper(ctx, u, t0, m.method, m.rtol, m.atol) if u.continuous else u
    sched = topo_schedule(ctx, units, watched_out_nodes(ctx))
    # Gauss–Seidel order: signal flow, sources first
    flow = flow_order(ctx, units)
    per_unit_set = {u.name: setter_op(ctx, u, list(range(len(u.input_names))), input_sources(ctx, u))
                    for u in units if u.input_names}
    per_unit_get = {u.name: u.output_getter(list(range(len(u.output_names)))) for u in units if u.output_names}
    stepped = [u for u in flow if u.name in steppers]
    memoryless = [u for u in units if u.memoryless]

    takes_discrete = [s for s in steppers.values() if isinstance(s, MeStepper) and s.unit.has_discrete_inputs]

    def consistent(t: float) -> None:
        """Every input and output at t; ME units take changed discrete inputs in event mode there
        (and the others see what that changes), so recorded values are those after the event."""
        for _ in range(100):
            ctx.t = t
            for u in memoryless:
                u.set_time(t)
            for op in sched:
                op()
            pending = [s for s in takes_discrete if s.unit.discrete_inputs_changed()]
            if not pending:
                return
            for s in pending:
                s.group.handle_event(t)
        raise StepError(",".join(s.unit.name for s in pending), t, "discrete inputs kept changing in 100 event "
                        "iterations at one communication point", function="event iteration",
                        cause="a loop of discrete signals without a delay")

    check = output_checker(ctx, units)
    consistent(t0)
    check(t0)
    ctx.record(t0)
    h = m.step_s
    t = t0
    scale = {u.name: [abs(u.inbuf[i]) for i in range(len(u.input_names))] for u in stepped}
    estimated = {u.name: continuous_inputs(ctx, u) for u in stepped}
    n_steps = n_rejected = 0
    eps = 1e-12 * max(1.0, abs(t_end))
    gs = m.coupling == "gauss-seidel"
    wall_start = time.perf_counter()
    misses, worst_lateness = 0, 0.0
    while t < t_end - eps:
        if m.realtime:
            # Hardware in the loop: a step may not start before its wall-clock time; one that
            # starts more than a step late missed its deadline (the device saw a stale command).
            lateness = time.perf_counter() - wall_start - (t - t0)
            if lateness < 0:
                time.sleep(-lateness)
            elif lateness > h:
                misses += 1
                ctx.late_steps.append((t, lateness))   # cosim.validity judges the periods
            worst_lateness = max(worst_lateness, lateness)
        h_try = min(h, t_end - t)
        if t + h_try > t_end - 1e-9 * h_try:
            h_try = t_end - t
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
                        ctx.t = t + h_try
                        u.set_time(t + h_try)
                        if u.name in per_unit_set:
                            per_unit_set[u.name]()
                        if u.name in per_unit_get:
                            per_unit_get[u.name]()
                        continue
                    ctx.t = t
                    if u.name in per_unit_set:
                        per_unit_set[u.name]()
                    used[u.name] = list(u.inbuf)[: len(u.input_names)]
                    steppers[u.name].do_step(t, h_try)
                    if u.name in per_unit_get:
                        per_unit_get[u.name]()
            else:
                for u in stepped:
                    used[u.name] = list(u.inbuf)[: len(u.input_names)]
                ctx.t = t
                for u in stepped:
                    steppers[u.name].do_step(t, h_try)
            consistent(t + h_try)
        except StepError as exc:
            if m.adaptive and saved is not None and h_try > m.min_step_s and "discard" in str(exc):
                for n, s in steppers.items():
                    s.set_state(saved[n])
                consistent(t)
                h = h_try * 0.25
                n_rejected += 1
                continue
            raise
        if m.adaptive:
            err = 0.0
            for u in stepped:
                sc = scale[u.name]
                for i in estimated[u.name]:
                    old, new = used[u.name][i], u.inbuf[i]
                    sc[i] = max(sc[i], abs(new))
                    e = 0.5 * abs(new - old) / (m.atol + m.macro_rtol * sc[i])
                    if e > err:
                        err = e
            if err > 1.0 and h_try > m.min_step_s * 1.0001:
                for n, s in steppers.items():
                    s.set_state(saved[n])
                    s.free_state(saved[n])
                consistent(t)
                h = max(m.min_step_s, h_try * max(0.2, 0.9 / err))
                n_rejected += 1
                continue
            for n, s in steppers.items():
                s.free_state(saved[n])
            h = min(m.max_macro_step_s, h_try * min(2.0, 0.9 / max(err, 1e-12)))
        t = t + h_try
        n_steps += 1
        check(t)
        ctx.record(t)
        if n_steps % 256 == 0:
            ctx.tick(t)
    ctx.stats.update({"macro_steps": n_steps, "rejected_steps": n_rejected})
    if m.realtime:
        ctx.stats.update({"deadline_misses": misses, "worst_lateness_s": worst_lateness})
    check_all_rows(ctx)
