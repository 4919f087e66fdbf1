"""A group of units integrated together as one ODE by CVODE: the strong coupling's whole
system, the mixed coupling's inner group, or one Model Exchange unit inside a weak coupling.

Each right-hand-side evaluation sets time and states on every unit and then walks the schedule
(featherstar.cosim.coupling.schedule); state and time events of generic ME FMUs are handled
(root finding, event iteration, re-initialisation).
"""
from __future__ import annotations

import ctypes
import math
from ctypes import c_double
from typing import Any, Callable, Sequence

import numpy as np

from ..errors import StepError
from ..framework.units import Unit
from ._cvode import N_VGET_ARRAY_POINTER_ADDRESS, CVodeError, CVodeIntegrator
from .compiled_rhs import compile_rhs
from .context import Context
from .schedule import Step
from .system import System


class OdeGroup:
    """Units integrated together as one ODE by CVODE."""

    def __init__(self, system: System, context: Context, units: Sequence[Unit],
                 rhs_steps: list[Step], t0: float, *, method: str, rtol: float, atol: float,
                 max_step: float = 0.0, check_finite: bool = False, compiled: bool = True) -> None:
        self.system = system
        self.context = context
        self.units = list(units)
        self.timed = [u for u in units if u.continuous or u.memoryless]
        self.stateful: list[tuple[Unit, int]] = []
        off = 0
        for u in units:
            if u.continuous and u.n_states > 0:
                self.stateful.append((u, off))
                off += u.n_states
        self.n = max(off, 1)
        self.dummy = off == 0
        self.ops = [step.run for step in rhs_steps]
        self.event_units = [u for u in units if u.continuous and u.n_events > 0]
        # Python blocks whose outputs jump at known instants (a sampled command): the solver
        # stops and restarts there
        self.clocked = [u for u in units if not u.continuous and u.next_time_event() is not None]
        self.n_events = sum(u.n_events for u in self.event_units)
        self.needs_completed = [u for u in units if u.continuous and u.needs_completed_step]
        self.discrete_units = [u for u in units if u.continuous and u.has_discrete_inputs]
        self.check_finite = check_finite
        self._ydot_type = c_double * self.n
        x0 = self._initial_states()
        rhs = self._rhs if (check_finite or self.dummy) else self._compiled_or_fast_rhs(rhs_steps, compiled)
        lmm, _, nonlinear = method.partition("-")
        self.cv = CVodeIntegrator(self.n, rhs, t0, x0, method=lmm, nonlinear=nonlinear or "newton",
                                  rtol=rtol, atol=atol,
                                  max_step=max_step, n_roots=self.n_events,
                                  roots=self._roots if self.n_events else None)
        # the unit that asked to end the simulation (terminateSimulation): the model's normal way
        # to say it is done, so the run ends there without an error
        self.terminated_by = ""

    def _initial_states(self) -> list[float]:
        x = (c_double * self.n)()
        for u, off in self.stateful:
            u.get_states(ctypes.addressof(x) + 8 * off)
        return list(x)

    def _rhs(self, t: float, y: int, yd: int) -> int:
        self.context.t = t
        for u in self.timed:
            u.set_time(t)
        for u, off in self.stateful:
            u.set_states(y + 8 * off)
        for op in self.ops:
            op()
        if self.dummy:
            self._ydot_type.from_address(yd)[0] = 0.0
            return 0
        for u, off in self.stateful:
            u.get_derivatives(yd + 8 * off)
        if self.check_finite and not math.isfinite(sum(self._ydot_type.from_address(yd))):
            return 1  # recoverable: CVODE retries with a smaller step, then fails if it persists
        # (off by default: a NaN derivative fails CVODE's error test anyway, and `diagnose`
        # then names the block and state; the check costs ~5 µs per call at 45 states)
        return 0

    def _compiled_or_fast_rhs(self, steps: list[Step], compiled: bool) -> Any:
        """The right-hand side compiled into C calls (featherstar.cosim.coupling.compiled_rhs) when the
        group allows it, else `_fast_rhs`; context.stats["rhs"] says which and why."""
        if compiled:
            program = compile_rhs(self.context, self.timed, self.stateful, steps, N_VGET_ARRAY_POINTER_ADDRESS)
            if not isinstance(program, str):
                self.context.stats["rhs"] = "compiled"
                return program
            self.context.stats["rhs"] = f"python ({program})"
        else:
            self.context.stats["rhs"] = "python (master.compiled_rhs = false)"
        return self._fast_rhs()

    def _fast_rhs(self) -> Callable[[float, int, int], int]:
        """`_rhs` through each unit's public fast path (featherstar.cosim.framework.units.FastPath: the raw FMI entry
        points of an FMU, bound once), with the loops' lists captured as locals."""
        context = self.context
        set_time = tuple(u.fast_path().set_time for u in self.timed)
        set_states = tuple((u.fast_path().set_states, 8 * off) for u, off in self.stateful)
        get_derivatives = tuple((u.fast_path().get_derivatives, 8 * off) for u, off in self.stateful)
        ops = tuple(self.ops)

        def rhs(t: float, y: int, yd: int) -> int:
            context.t = t
            for f in set_time:
                f(t)
            for f, off in set_states:
                f(y + off)
            for op in ops:
                op()
            for f, off in get_derivatives:
                f(yd + off)
            return 0
        return rhs

    def _roots(self, t: float, y: int, gout: int) -> int:
        self.set_point(t, y)
        off = 0
        for u in self.event_units:
            u.get_event_indicators(gout + 8 * off)
            off += u.n_events
        return 0

    def set_point(self, t: float, y_address: int) -> None:
        """Put every unit at (t, y) with consistent inputs and outputs."""
        self.context.t = t
        for u in self.timed:
            u.set_time(t)
        for u, off in self.stateful:
            u.set_states(y_address + 8 * off)
        for op in self.ops:
            op()

    def next_time_event(self) -> float:
        times = [u.next_time_event() for u in self.units if u.continuous] + [u.next_time_event() for u in self.clocked]
        times = [t for t in times if t is not None]
        return min(times) if times else math.inf

    def handle_event(self, t: float) -> bool:
        """Event iteration at t; reinitialises CVODE. Returns terminate.

        Every event-capable unit updates its discrete states first; then, in super-dense time,
        units whose discrete inputs changed (a discrete output of another unit moved) enter
        event mode again to take them, until nothing changes."""
        eps = 1e-12 * max(1.0, abs(t))
        for u in self.clocked:
            due_at = u.next_time_event()
            if due_at is not None and due_at <= t + eps:
                u.time_event(t)
        self.set_point(t, self.cv.y_address)
        terminate = False
        for round_ in range(100):
            due = [u for u in self.units if u.continuous and (
                u.discrete_inputs_changed() or (round_ == 0 and (u.n_events or u.next_time_event() is not None
                                                                 or u.needs_completed_step)))]
            if not due:
                break
            changed_any = False
            for u in due:
                changed, _next, term = u.event_update()
                changed_any |= changed
                if term and not terminate:
                    self.terminated_by = u.name
                terminate |= term
            if changed_any:
                for u, off in self.stateful:
                    u.get_states(self.cv.y_address + 8 * off)
            self.set_point(t, self.cv.y_address)
        else:
            names = ", ".join(u.name for u in self.discrete_units if u.discrete_inputs_changed())
            raise StepError(names or "master", t, "discrete inputs kept changing in 100 event iterations at one instant",
                            function="event iteration", cause="a loop of discrete signals without a delay")
        self.cv.reinit(t)
        self.context.stats["events"] = self.context.stats.get("events", 0) + 1
        return terminate

    def discrete_inputs_pending(self, t: float) -> bool:
        """Sample the discrete inputs at t (a communication point): does one wait for event mode?"""
        self.set_point(t, self.cv.y_address)
        return any(u.discrete_inputs_changed() for u in self.discrete_units)

    def integrate(self, t_target: float, t_end: float, out_times: np.ndarray, k: int,
                  on_output: Callable[[float, int], None]) -> tuple[int, bool]:
        """Integrate to t_target (<= t_end, the run's end), calling on_output(t, y_address) at
        each output time out_times[k:] <= t_target (it puts every unit at that point). Returns the index of the next output
        time and whether a unit asked to terminate. Without events the stop time is t_end, so
        integrating in chunks takes the same steps as one call; with events the solver stops at
        t_target (and at each time event).

        Discrete inputs of Model Exchange FMUs are sampled at the output times and at events;
        when one changed, the integration stops there and its FMU enters event mode to take it.
        At an event time the recorded values are those after the event."""
        cv = self.cv
        n_out = len(out_times)
        sampled = bool(self.discrete_units)
        simple = not self.event_units and not self.needs_completed and self.next_time_event() == math.inf and not sampled
        eps = 1e-12 * max(1.0, abs(t_end))
        if sampled and self.discrete_inputs_pending(cv.t) and self.handle_event(cv.t):
            return k, True
        while k < n_out and out_times[k] <= cv.t + eps:
            on_output(out_times[k], cv.y_address)
            k += 1
        if simple:
            cv.set_stop_time(t_end)
            while k < n_out and out_times[k] <= t_target + eps:
                tout = min(out_times[k], t_end)
                cv.advance(tout)
                on_output(tout, cv.y_address)
                k += 1
            if cv.t < t_target - eps:
                cv.advance(t_target)
            self.set_point(cv.t, cv.y_address)
            return k, False
        while cv.t < t_target - eps:
            t_stop = min(t_target, self.next_time_event())
            if sampled and k < n_out:
                t_stop = min(t_stop, out_times[k])
            cv.set_stop_time(t_stop)
            flag = cv.advance(t_stop, one_step=True)
            t_cur = cv.t
            while k < n_out and out_times[k] < t_cur - eps:
                y = cv.interpolate(out_times[k])
                on_output(out_times[k], ctypes.addressof(y))
                k += 1
            event = flag == 2 or abs(t_cur - self.next_time_event()) <= eps
            if self.needs_completed and not event:
                self.set_point(t_cur, cv.y_address)
                for u in self.needs_completed:
                    enter, term = u.completed_integrator_step()
                    event |= enter
                    if term:
                        self.terminated_by = u.name
                        return k, True
            if not event and sampled and abs(t_cur - t_stop) <= eps:
                event = self.discrete_inputs_pending(t_cur)
            terminate = event and self.handle_event(t_cur)
            while k < n_out and out_times[k] <= t_cur + eps:
                on_output(out_times[k], cv.y_address)
                k += 1
            if terminate:
                return k, True
        self.set_point(cv.t, cv.y_address)
        return k, False

    def diagnose(self, exc: CVodeError) -> StepError:
        """Why did CVODE fail? Look at every unit at the last successful state, and at the time
        where the solver gave up: the first non-finite output in signal-flow order is the origin."""
        t_good = self.cv.t
        cause = str(exc)
        t_fail = _time_in(self.cv.last_error, t_good)
        y = list(self.cv.y)
        ydot = (c_double * self.n)()
        flow = [u for u in self.system.flow_order(list(self.system.units.values())) if u in self.units]
        probes = [t_good, t_fail] + [t_fail + d * max(1.0, abs(t_fail)) for d in (1e-12, 1e-10, 1e-8, 1e-6, 1e-4)]
        for t in probes:
            try:
                self.set_point(t, self.cv.y_address)
            except StepError as inner:
                return inner
            for u in flow:
                for i in range(len(u.output_names)):
                    if not math.isfinite(u.outbuf[i]):
                        return StepError(u.name, t, f"output {u.output_names[i]} = {u.outbuf[i]}",
                                         function="CVODE", cause="the block produced NaN/inf (division by zero, "
                                         "invalid parameters or inputs out of range); the solver then failed: " + cause)
            worst: tuple[float, str, str] | None = None
            for u, off in self.stateful:
                names = u.state_names() or [f"x{i}" for i in range(u.n_states)]
                try:
                    u.get_derivatives(ctypes.addressof(ydot) + 8 * off)
                except StepError as inner:
                    return inner
                for i in range(u.n_states):
                    xi, di = y[off + i], ydot[off + i]
                    if not (math.isfinite(xi) and math.isfinite(di)):
                        return StepError(u.name, t, f"state {names[i]} = {xi}, derivative {di}: NaN/inf",
                                         function="CVODE", cause="the model divided by zero or left its valid range")
                    size = abs(di) / (1.0 + abs(xi))
                    if worst is None or size > worst[0]:
                        worst = (size, u.name, names[i])
        if worst is not None:
            block, state = worst[1], worst[2]
            return StepError(block, t_good, f"the solver failed: {cause}", function="CVODE",
                             cause=f"fastest-changing state is {block}.{state} (|dx/dt|/(1+|x|) = {worst[0]:.3g}): "
                             "a blow-up or a very stiff transient in that block; check its parameters, or try master.method = bdf")
        return StepError(self.units[0].name if self.units else "master", t_good, f"the solver failed: {cause}",
                         function="CVODE")


def _time_in(message: str, default: float) -> float:
    import re

    match = re.search(r"t\s*=\s*([-+0-9.eE]+)", message or "")
    try:
        return float(match.group(1)) if match else default
    except ValueError:
        return default
