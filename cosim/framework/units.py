"""Runtime units: what the master drives during one run (built per run, never shared).

A unit wraps one instantiated block. Port values travel through per-unit ctypes buffers
(`inbuf`, `outbuf`) so the hot loop (the strong master's right-hand side) does no dict or numpy
work: the master copies source outputs into inputs, then asks the unit to push inputs to its
model (`input_setter(idx)`) and to compute outputs into outbuf (`output_getter(idx)`).

Model Exchange side (continuous units): set_time, set_states(address), get_derivatives(address),
get_states(address), event indicators and event updates.
Co-simulation side (stepped units): do_step(t, h) with the inputs held, get_state / set_state
for rollback.

Implementations here: PyUnit (a Python Block; memoryless ones are evaluated at any instant) and
ModelUnit (a fmu_src Model evaluated in-process with CasADi: `master.backend = "casadi"`).
FMUs are in featherstar.cosim.fmi.fmu_block (the only module that calls fmpy).
"""
from __future__ import annotations

import ctypes
from ctypes import c_double
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

from ..errors import StepError


def _buffer(n: int) -> ctypes.Array:
    return (c_double * max(n, 1))()


@dataclass(frozen=True)
class FastPath:
    """The three calls the strong coupling's right-hand side makes, bound once per run: set the
    time, set the continuous states from an address, write the derivatives to an address. A unit
    offers the quickest form it has (an FMU: its raw FMI entry points); each raises StepError on
    a failed call, as the unit's methods do."""

    set_time: Callable[[float], None]
    set_states: Callable[[int], None]
    get_derivatives: Callable[[int], None]


@dataclass(frozen=True)
class NativeCalls:
    """A Model Exchange unit's C entry points for the compiled right-hand side
    (featherstar.cosim.coupling.compiled_rhs): addresses of its FMI functions and of the instance they
    take. `fmi3` selects fmi3Set/GetFloat64 over FMI 2's Set/GetReal for the ports. `inputs` and
    `outputs` are the port indices whose values travel as plain float64 through those calls;
    other ports take the Python path."""

    instance: int
    fmi3: bool
    set_time: int
    set_states: int
    get_derivatives: int
    set_float64: int
    get_float64: int
    value_refs_in: tuple[int, ...]
    value_refs_out: tuple[int, ...]
    inputs: frozenset[int]
    outputs: frozenset[int]


class Unit:
    name: str = ""
    memoryless = False
    static = False  # outputs never change (constants): set once, skipped in the hot loop
    continuous = False  # has continuous states integrated by the master (ME)
    can_rollback = False
    can_iterate = True
    n_states = 0
    n_events = 0
    needs_completed_step = False
    has_discrete_inputs = False  # ME FMUs: inputs settable in event mode only (cosim.strong)
    # set (to the time) when the unit asked to end the run (FMI terminateSimulation): the
    # coupling stops there normally; a restored earlier state clears it
    terminated_at_s: float | None = None

    def __init__(self, name: str, input_names: Sequence[str], output_names: Sequence[str]) -> None:
        self.name = name
        self.input_names = list(input_names)
        self.output_names = list(output_names)
        self.inbuf = _buffer(len(self.input_names))
        self.outbuf = _buffer(len(self.output_names))
        self.t = 0.0

    # lifecycle
    def start(self, t0: float, t_end: float, rtol: float) -> None:
        self.t = t0

    def close(self) -> None:
        pass

    # instant evaluation
    def input_setter(self, idx: Sequence[int]) -> Callable[[], None]:
        raise NotImplementedError

    def output_getter(self, idx: Sequence[int]) -> Callable[[], None]:
        raise NotImplementedError

    def set_time(self, t: float) -> None:
        self.t = t

    # ME
    def set_states(self, address: int) -> None:
        pass

    def get_states(self, address: int) -> None:
        pass

    def get_derivatives(self, address: int) -> None:
        pass

    def fast_path(self) -> FastPath:
        return FastPath(self.set_time, self.set_states, self.get_derivatives)

    def status_error(self, function: str, t: float, status: int) -> StepError:
        """The error for a call of this unit that returned a bad status (FMI numbering)."""
        return StepError(self.name, t, f"{function} returned status {status}", function=function)

    def native_calls(self) -> NativeCalls | None:
        """The unit's C entry points, if it has them (FMUs in Model Exchange)."""
        return None

    def time_function(self) -> tuple[Any, list[float]] | None:
        """A memoryless unit without inputs may give its outputs as a CasADi Function f(t, p)
        (one scalar result per output, in order) and the values of p for this run: the compiled
        right-hand side evaluates it in C."""
        return None

    def state_names(self) -> list[str]:
        return []

    def get_event_indicators(self, address: int) -> None:
        pass

    def completed_integrator_step(self) -> tuple[bool, bool]:
        return False, False

    def event_update(self) -> tuple[bool, float | None, bool]:
        """Enter event mode, iterate discrete states, return to continuous time.
        Returns (continuous states changed, next time event or None, terminate)."""
        return False, None, False

    def next_time_event(self) -> float | None:
        return None

    def time_event(self, t: float) -> None:
        """The master reached this (non-continuous) unit's time event at t: schedule the next."""

    def discrete_inputs_changed(self) -> bool:
        """True when a discrete input's value in inbuf waits to be set in event mode (ME FMUs)."""
        return False

    # CS
    def do_step(self, t: float, h: float) -> None:
        self.t = t + h

    def get_state(self) -> Any:
        return self.t

    def set_state(self, state: Any) -> None:
        self.t = state

    def free_state(self, state: Any) -> None:
        pass


class PyUnit(Unit):
    """A Python block. Memoryless blocks (with `evaluate`) are computed at any instant, so they
    live inside the strong master's right-hand side."""

    def __init__(self, block: Any) -> None:
        super().__init__(block.name, list(block.inputs), list(block.outputs))
        self.block = block
        self.memoryless = hasattr(block, "evaluate")
        self.static = bool(getattr(block, "static", False)) and not self.input_names
        self.continuous = False
        from .block import can_iterate as _ci

        self.can_iterate = _ci(block)
        self.can_rollback = self.memoryless or (hasattr(block, "get_state") and hasattr(block, "set_state"))
        self._inputs = {n: 0.0 for n in self.input_names}
        # a memoryless block without inputs may offer outputs_at(t_s) -> its output values in
        # `outputs` order (the stroke controller): the hot loop then skips the dicts
        self._fast = getattr(block, "outputs_at", None) if self.memoryless and not self.input_names else None
        # a block whose outputs jump at known instants (a sampled command) offers next_sample_s(t)
        self._next_sample = getattr(block, "next_sample_s", None)
        self._next_event: float | None = None

    def time_function(self) -> tuple[Any, list[float]] | None:
        offer = getattr(self.block, "time_function", None)
        return offer() if offer is not None and self._fast is not None else None

    def start(self, t0: float, t_end: float, rtol: float) -> None:
        self.t = t0
        try:
            self.block.start(t0)
        except StepError:
            raise
        except Exception as exc:
            raise StepError(self.name, t0, f"start() failed: {exc}", function="start") from exc
        self._next_event = self._next_sample(t0) if self._next_sample is not None else None

    def next_time_event(self) -> float | None:
        return self._next_event

    def time_event(self, t: float) -> None:
        self._next_event = self._next_sample(t) if self._next_sample is not None else None

    def close(self) -> None:
        try:
            self.block.close()
        except Exception:
            pass

    def input_setter(self, idx: Sequence[int]) -> Callable[[], None]:
        names = [(i, self.input_names[i]) for i in idx]
        inbuf, inputs = self.inbuf, self._inputs
        if self.memoryless:
            def push() -> None:
                for i, n in names:
                    inputs[n] = inbuf[i]
        else:
            block = self.block

            def push() -> None:
                vals = {n: inbuf[i] for i, n in names}
                inputs.update(vals)
                block.set_inputs(vals)
        return push

    def output_getter(self, idx: Sequence[int]) -> Callable[[], None]:
        outbuf = self.outbuf
        pairs = [(i, self.output_names[i]) for i in idx]
        if self._fast is not None:
            fast = self._fast

            n = len(self.output_names)
            if n == 3:
                def get() -> None:
                    outbuf[0], outbuf[1], outbuf[2] = fast(self.t)
            else:
                def get() -> None:
                    for i, v in enumerate(fast(self.t)[:n]):
                        outbuf[i] = v
            return get
        if self.memoryless:
            evaluate, inputs = self.block.evaluate, self._inputs

            def get() -> None:
                values = evaluate(self.t, inputs)
                for i, n in pairs:
                    outbuf[i] = values[n]
        else:
            block = self.block

            def get() -> None:
                values = block.get_outputs()
                for i, n in pairs:
                    outbuf[i] = values[n]
        return get

    def do_step(self, t: float, h: float) -> None:
        try:
            self.block.do_step(t, h)
        except StepError:
            raise
        except Exception as exc:
            raise StepError(self.name, t, f"do_step failed: {exc}", function="do_step") from exc
        self.t = t + h

    def get_state(self) -> Any:
        inner = self.block.get_state() if hasattr(self.block, "get_state") else None
        return (self.t, dict(self._inputs), inner, self._next_event)

    def set_state(self, state: Any) -> None:
        self.t, inputs, inner, self._next_event = state
        self._inputs.update(inputs)
        if hasattr(self.block, "set_state"):
            self.block.set_state(inner)


class ModelUnit(Unit):
    """A fmu_src Model evaluated in-process (CasADi), offering the Model Exchange interface."""

    continuous = True
    can_rollback = True

    def __init__(self, name: str, model: Any, parameters: dict[str, float]) -> None:
        super().__init__(name, [v.name for v in model.inputs], [v.name for v in model.outputs])
        import casadi as ca

        self.model = model
        self.n_states = model.x.numel()
        p = np.array(model.parameter_vector(parameters), dtype=float)
        fy = ca.Function("y", [model.x, model.u], [ca.substitute(model.y, model.p, ca.DM(p))])
        fx = ca.Function("xdot", [model.x, model.u], [ca.substitute(model.xdot, model.p, ca.DM(p))])
        self.x = np.array(model.initial_state(), dtype=float)
        self.u = np.array([v.start for v in model.inputs], dtype=float)
        self.y = np.zeros(len(self.output_names))
        self.xd = np.zeros(self.n_states)
        # CasADi function buffers: ~0.1 µs per call on preallocated arrays (vs ~50 µs via DM)
        self._fns = []
        for fn, res in ((fy, self.y), (fx, self.xd)):
            buf, call = fn.buffer()
            buf.set_arg(0, memoryview(self.x))
            buf.set_arg(1, memoryview(self.u))
            buf.set_res(0, memoryview(res))
            self._fns.append((buf, call))
        self._eval_y = self._fns[0][1]
        self._eval_xd = self._fns[1][1]
        self._y_valid = False

    def state_names(self) -> list[str]:
        return [s.name for s in self.model.states]

    def input_setter(self, idx: Sequence[int]) -> Callable[[], None]:
        idx = list(idx)
        inbuf, u = self.inbuf, self.u

        def push() -> None:
            for i in idx:
                u[i] = inbuf[i]
            self._y_valid = False
        return push

    def output_getter(self, idx: Sequence[int]) -> Callable[[], None]:
        idx = list(idx)
        outbuf = self.outbuf

        y = self.y

        def get() -> None:
            if not self._y_valid:
                self._eval_y()
                self._y_valid = True
            for i in idx:
                outbuf[i] = y[i]
        return get

    def set_states(self, address: int) -> None:
        ctypes.memmove(self.x.ctypes.data, address, 8 * self.n_states)
        self._y_valid = False

    def get_states(self, address: int) -> None:
        ctypes.memmove(address, self.x.ctypes.data, 8 * self.n_states)

    def get_derivatives(self, address: int) -> None:
        self._eval_xd()
        ctypes.memmove(address, self.xd.ctypes.data, 8 * self.n_states)

    def get_state(self) -> Any:
        return (self.t, self.x.copy(), self.u.copy())

    def set_state(self, state: Any) -> None:
        self.t, x, u = state
        self.x[:] = x
        self.u[:] = u
        self._y_valid = False
