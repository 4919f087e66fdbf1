"""The FMU adapter: every fmpy call of featherstar's master lives here (what is known before
loading the binary is featherstar.cosim.fmi.fmu_info).

`FmuUnit` instantiates one FMU as Model Exchange ("me": the master integrates its states) or
Co-Simulation ("cs": the FMU steps itself). The calls made in the master's hot loop (set time,
states and inputs; get derivatives and outputs; doStep) go through raw ctypes prototypes on
preallocated arrays — fmpy's own wrappers cost several µs per call — and their status codes are
checked here; ports of other types go through featherstar.cosim.fmi.fmu_values. Every failure becomes a
StepError naming the block, the FMI function and the time (fmpy's FMICallException names neither
the instance nor the time) and quoting the FMU's own log lines.

Model Exchange discrete inputs can be set only in event mode: the setters leave them in inbuf,
`discrete_inputs_changed` tells the master, and `event_update` sets them in event mode.
"""
from __future__ import annotations

import ctypes
import math
import shutil
import tempfile
from collections import deque
from ctypes import CFUNCTYPE, c_bool, c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path
from typing import Any, Callable, Sequence

from fmpy.fmi1 import FMICallException

from ..errors import StepError
from ..framework.block import Port
from ..framework.units import FastPath, NativeCalls, Unit
from .bounded_zip import extract_bounded
from .fmu_info import FmuInfo, read_fmu_info
from .fmu_values import TypedAccess, TypedPorts
from .probe import probe_fmu

STATUS = ["ok", "warning", "discard", "error", "fatal", "pending"]


_P = c_void_p  # every array argument is passed as a raw address


def _address(dll: Any, name: str) -> int:
    return ctypes.cast(getattr(dll, name), c_void_p).value


def _proto(dll: Any, name: str, *argtypes: Any) -> Callable[..., int]:
    return CFUNCTYPE(c_int, *argtypes)(_address(dll, name))


class FmuUnit(Unit):
    """One FMU instance, Model Exchange (`mode="me"`) or Co-Simulation (`mode="cs"`)."""

    def __init__(self, name: str, info: FmuInfo, parameters: dict[str, Any], mode: str,
                 unzip_dir: str | None = None) -> None:
        super().__init__(name, list(info.inputs), list(info.outputs))
        self.info = info
        self.mode = mode
        self.parameters = dict(parameters)
        self.continuous = mode == "me"
        self.n_states = info.n_states if mode == "me" else 0
        self.n_events = info.n_event_indicators if mode == "me" else 0
        self.needs_completed_step = info.needs_completed_integrator_step and mode == "me"
        self.can_rollback = info.can_get_set_state or mode == "me"
        self.fmi3 = info.fmi_version.startswith("3.")
        self._unzip = unzip_dir
        self._own_unzip = False
        self.fmu: Any = None
        self._time_event: float | None = None
        self.terminated_at_s: float | None = None
        self._vr_in = (c_uint * max(len(self.input_names), 1))(*[info.vr[n] for n in self.input_names])
        self._vr_out = (c_uint * max(len(self.output_names), 1))(*[info.vr[n] for n in self.output_names])
        self.port_in = [info.port_vars[n] for n in self.input_names]
        self.port_out = [info.port_vars[n] for n in self.output_names]
        # Model Exchange: discrete inputs may be set in event mode only; the master's setters leave
        # them in inbuf and the event update pushes them (cosim.strong enters event mode for that)
        self._discrete_in = [i for i, pv in enumerate(self.port_in) if pv.discrete] if mode == "me" else []
        self.has_discrete_inputs = bool(self._discrete_in)
        self._pushed: dict[int, float] = {}
        self.log_lines: deque[tuple[int, str]] = deque(maxlen=8)

    # ---------------------------------------------------------------------------------------
    def _fail(self, function: str, t: float, status: int | str, cause: str = "") -> StepError:
        label = STATUS[status] if isinstance(status, int) and 0 <= status < len(STATUS) else status
        said = self.fmu_said()
        message = f"{function} returned status {label}" + (f"; the FMU logged: {said}" if said else "")
        return StepError(self.name, t, message, function=function, recoverable=status == 2,   # Discard
                         cause=cause or "the FMU rejected the call (invalid inputs or parameters, or the "
                         "model left its valid range)")

    def status_error(self, function: str, t: float, status: int) -> StepError:
        return self._fail(function, t, status)

    def fmu_said(self) -> str:
        """The FMU's own recent log lines (warnings and errors first), for error messages."""
        lines = [text for status, text in self.log_lines if status >= 1] or [text for _, text in self.log_lines][-1:]
        self.log_lines.clear()
        return " | ".join(dict.fromkeys(lines))

    def _log(self, status: int, message: bytes | None) -> None:
        self.log_lines.append((int(status), (message or b"").decode("utf-8", "replace").strip()))

    def _call(self, function: str, fn: Callable[[], Any]) -> Any:
        try:
            return fn()
        except FMICallException as exc:
            raise self._fail(exc.function, self.t, exc.status) from None
        except StepError:
            raise
        except Exception as exc:
            raise StepError(self.name, self.t, f"{function} failed: {exc}", function=function) from None

    def start(self, t0: float, t_end: float, rtol: float) -> None:
        info = self.info
        self.t = t0
        if self._unzip is None:
            self._unzip = tempfile.mkdtemp(prefix=f"featherstar-{self.name}-")
            self._own_unzip = True
            self._call("extract", lambda: extract_bounded(Path(info.path), Path(self._unzip), f"FMU '{info.path}'"))
        md = info.model_description
        iface = md.coSimulation if self.mode == "cs" else md.modelExchange
        crash = probe_fmu(Path(info.path), self._unzip, md.guid, iface.modelIdentifier, info.fmi_version, self.mode)
        if crash is not None:   # loading it here would take the master down with it
            raise StepError(self.name, t0, f"FMU '{info.path}' {crash} when probed in a child process; "
                            "featherstar does not load it", function="probe",
                            cause="a faulty, truncated or incompatible binary")
        kw = dict(guid=md.guid, unzipDirectory=self._unzip, modelIdentifier=iface.modelIdentifier,
                  instanceName=self.name)
        if self.fmi3:
            from fmpy.fmi3 import FMU3Model, FMU3Slave

            self.fmu = (FMU3Slave if self.mode == "cs" else FMU3Model)(**kw)
            self._call("instantiate", lambda: self.fmu.instantiate(logMessage=self._log3))
        else:
            from fmpy.fmi2 import FMU2Model, FMU2Slave

            self.fmu = (FMU2Slave if self.mode == "cs" else FMU2Model)(**kw)
            self._callbacks = self._fmi2_callbacks()
            self._call("instantiate", lambda: self.fmu.instantiate(callbacks=self._callbacks))
        self._bind()
        fmu = self.fmu
        by_type: dict[str, tuple[list[int], list[Any]]] = {}
        for key, value in self.parameters.items():
            vrs, vals = by_type.setdefault(info.parameter_types.get(key, "Float64"), ([], []))
            vrs.append(info.parameters[key])
            vals.append(value)
        for type_, (vrs, vals) in by_type.items():
            status = self._access.set(type_, vrs, vals)
            if status > 1:
                raise self._fail(f"{self._access.name('Set', type_)} (parameters)", t0, status)
        if self.fmi3:
            self._call("fmi3EnterInitializationMode",
                       lambda: fmu.enterInitializationMode(tolerance=rtol, startTime=t0, stopTime=t_end))
            self._call("fmi3ExitInitializationMode", fmu.exitInitializationMode)
        else:
            self._call("fmi2SetupExperiment", lambda: fmu.setupExperiment(tolerance=rtol, startTime=t0, stopTime=t_end))
            self._call("fmi2EnterInitializationMode", fmu.enterInitializationMode)
            self._call("fmi2ExitInitializationMode", fmu.exitInitializationMode)
        if self.mode == "me":
            self._event_iteration()  # a request to terminate here ends the run at t0
            self._call("enterContinuousTimeMode", fmu.enterContinuousTimeMode)

    def _log3(self, env, status, category, message) -> None:
        self._log(status, message)

    def _fmi2_callbacks(self) -> Any:
        """fmi2CallbackFunctions whose logger keeps the FMU's lines (fmpy's native proxy formats
        the variadic message first)."""
        from fmpy import calloc, free
        from fmpy.fmi2 import (
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(lambda env, name, status, category, message: self._log(status, message))
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        try:
            from fmpy.logging import addLoggerProxy

            addLoggerProxy(ctypes.byref(callbacks))
        except Exception:  # no native proxy for this platform: messages arrive unformatted
            pass
        return callbacks

    def _bind(self) -> None:
        dll = self.fmu.dll
        inst = self.fmu.component
        self._inst = inst
        self._access = TypedAccess(dll, inst, self.fmi3)
        self._typed = TypedPorts(self._access, self.port_in, self.port_out, self.output_names, self.inbuf,
                                 self.outbuf, fail=lambda function, status: self._fail(function, self.t, status),
                                 carry_error=lambda message, function: StepError(
                                     self.name, self.t, message, function=function,
                                     cause="featherstar carries integers as float64, exact to 2**53"))
        pre = "fmi3" if self.fmi3 else "fmi2"
        if self.fmi3:
            self._setf = _proto(dll, "fmi3SetFloat64", c_void_p, _P, c_size_t, _P, c_size_t)
            self._getf = _proto(dll, "fmi3GetFloat64", c_void_p, _P, c_size_t, _P, c_size_t)
        else:
            set2 = _proto(dll, "fmi2SetReal", c_void_p, _P, c_size_t, _P)
            get2 = _proto(dll, "fmi2GetReal", c_void_p, _P, c_size_t, _P)
            self._setf = lambda i, vr, n, v, m: set2(i, vr, n, v)
            self._getf = lambda i, vr, n, v, m: get2(i, vr, n, v)
        if self.mode == "me":
            self._set_time = _proto(dll, f"{pre}SetTime", c_void_p, c_double)
            self._set_x = _proto(dll, f"{pre}SetContinuousStates", c_void_p, _P, c_size_t)
            self._get_x = _proto(dll, f"{pre}GetContinuousStates", c_void_p, _P, c_size_t)
            self._get_dx = _proto(dll, "fmi3GetContinuousStateDerivatives" if self.fmi3 else "fmi2GetDerivatives",
                                  c_void_p, _P, c_size_t)
            self._get_z = _proto(dll, f"{pre}GetEventIndicators", c_void_p, _P, c_size_t)
        else:
            if self.fmi3:
                self._do_step3 = _proto(dll, "fmi3DoStep", c_void_p, c_double, c_double, c_bool,
                                        _P, _P, _P, _P)
                self._flags = (c_bool * 3)()
                self._last_t = c_double()
            else:
                self._do_step2 = _proto(dll, "fmi2DoStep", c_void_p, c_double, c_double, c_int)

    # --- instant evaluation --------------------------------------------------------------
    def input_setter(self, idx: Sequence[int]) -> Callable[[], None]:
        held = set(self._discrete_in)
        return self._setter([i for i in idx if i not in held])

    def _setter(self, idx: Sequence[int]) -> Callable[[], None]:
        fast = [i for i in idx if self.port_in[i].fast]
        typed = [i for i in idx if not self.port_in[i].fast]
        return _chain([self._fast_setter(fast) if fast else None, self._typed.setter(typed) if typed else None])

    def output_getter(self, idx: Sequence[int]) -> Callable[[], None]:
        fast = [i for i in idx if self.port_out[i].fast]
        typed = [i for i in idx if not self.port_out[i].fast]
        return _chain([self._fast_getter(fast) if fast else None, self._typed.getter(typed) if typed else None])

    def _fast_setter(self, idx: Sequence[int]) -> Callable[[], None]:
        idx = list(idx)
        n = len(idx)
        if n == 0:
            return lambda: None
        vr = (c_uint * n)(*[self._vr_in[i] for i in idx])
        vra = ctypes.addressof(vr)
        setf = self._setf
        if idx == list(range(idx[0], idx[0] + n)):
            vals_addr = ctypes.addressof(self.inbuf) + 8 * idx[0]

            def push() -> None:
                status = setf(self._inst, vra, n, vals_addr, n)
                if status > 1:
                    raise self._fail("SetFloat64 (inputs)", self.t, status)
        else:
            vals = (c_double * n)()
            vals_addr = ctypes.addressof(vals)
            inbuf = self.inbuf
            pairs = list(enumerate(idx))

            def push() -> None:
                for j, i in pairs:
                    vals[j] = inbuf[i]
                status = setf(self._inst, vra, n, vals_addr, n)
                if status > 1:
                    raise self._fail("SetFloat64 (inputs)", self.t, status)
        push._keep = vr  # keep the arrays alive with the closure
        return push

    def _fast_getter(self, idx: Sequence[int]) -> Callable[[], None]:
        idx = list(idx)
        n = len(idx)
        if n == 0:
            return lambda: None
        vr = (c_uint * n)(*[self._vr_out[i] for i in idx])
        vra = ctypes.addressof(vr)
        getf = self._getf
        if idx == list(range(idx[0], idx[0] + n)):
            vals_addr = ctypes.addressof(self.outbuf) + 8 * idx[0]

            def get() -> None:
                status = getf(self._inst, vra, n, vals_addr, n)
                if status > 1:
                    raise self._fail("GetFloat64 (outputs)", self.t, status)
        else:
            vals = (c_double * n)()
            vals_addr = ctypes.addressof(vals)
            outbuf = self.outbuf
            pairs = list(enumerate(idx))

            def get() -> None:
                status = getf(self._inst, vra, n, vals_addr, n)
                if status > 1:
                    raise self._fail("GetFloat64 (outputs)", self.t, status)
                for j, i in pairs:
                    outbuf[i] = vals[j]
        get._keep = vr
        return get

    def discrete_inputs_changed(self) -> bool:
        inbuf, pushed = self.inbuf, self._pushed
        return any(inbuf[i] != pushed.get(i) and inbuf[i] == inbuf[i] for i in self._discrete_in)

    def _push_discrete(self) -> None:
        """In event mode: set the discrete inputs the master has put in inbuf since the last event."""
        if not self._discrete_in:
            return
        if not hasattr(self, "_discrete_push"):
            self._discrete_push = self._setter(self._discrete_in)
        self._discrete_push()
        for i in self._discrete_in:
            self._pushed[i] = self.inbuf[i]

    # --- model exchange ------------------------------------------------------------------
    def set_time(self, t: float) -> None:
        self.t = t
        if self.mode == "me":
            status = self._set_time(self._inst, t)
            if status > 1:
                raise self._fail("SetTime", t, status)

    def set_states(self, address: int) -> None:
        status = self._set_x(self._inst, address, self.n_states)
        if status > 1:
            raise self._fail("SetContinuousStates", self.t, status)

    def get_states(self, address: int) -> None:
        status = self._get_x(self._inst, address, self.n_states)
        if status > 1:
            raise self._fail("GetContinuousStates", self.t, status)

    def get_derivatives(self, address: int) -> None:
        status = self._get_dx(self._inst, address, self.n_states)
        if status > 1:
            raise self._fail("GetContinuousStateDerivatives" if self.fmi3 else "GetDerivatives", self.t, status)

    def fast_path(self) -> FastPath:
        """The ME calls on the raw FMI entry points (fmpy's wrappers cost several µs per call); a
        bad status goes through the normal method, which raises the StepError."""
        if self.mode != "me":
            return super().fast_path()
        inst, set_time, set_x, get_dx, n = self._inst, self._set_time, self._set_x, self._get_dx, self.n_states

        def fast_set_time(t: float) -> None:
            self.t = t
            if set_time(inst, t) > 1:
                self.set_time(t)

        def fast_set_states(address: int) -> None:
            if set_x(inst, address, n) > 1:
                self.set_states(address)

        def fast_get_derivatives(address: int) -> None:
            if get_dx(inst, address, n) > 1:
                self.get_derivatives(address)
        return FastPath(fast_set_time, fast_set_states, fast_get_derivatives)

    def native_calls(self) -> NativeCalls | None:
        if self.mode != "me" or self.fmu is None:
            return None
        dll, pre = self.fmu.dll, "fmi3" if self.fmi3 else "fmi2"
        held = set(self._discrete_in)
        inst = self._inst
        return NativeCalls(
            instance=inst.value if isinstance(inst, c_void_p) else int(inst), fmi3=self.fmi3,
            set_time=_address(dll, f"{pre}SetTime"),
            set_states=_address(dll, f"{pre}SetContinuousStates"),
            get_derivatives=_address(dll, "fmi3GetContinuousStateDerivatives" if self.fmi3 else "fmi2GetDerivatives"),
            set_float64=_address(dll, "fmi3SetFloat64" if self.fmi3 else "fmi2SetReal"),
            get_float64=_address(dll, "fmi3GetFloat64" if self.fmi3 else "fmi2GetReal"),
            value_refs_in=tuple(self._vr_in[i] for i in range(len(self.input_names))),
            value_refs_out=tuple(self._vr_out[i] for i in range(len(self.output_names))),
            inputs=frozenset(i for i, pv in enumerate(self.port_in) if pv.fast and i not in held),
            outputs=frozenset(i for i, pv in enumerate(self.port_out) if pv.fast))

    def state_names(self) -> list[str]:
        return list(self.info.state_names)

    def get_event_indicators(self, address: int) -> None:
        status = self._get_z(self._inst, address, self.n_events)
        if status > 1:
            raise self._fail("GetEventIndicators", self.t, status)

    def completed_integrator_step(self) -> tuple[bool, bool]:
        enter, terminate = self._call("CompletedIntegratorStep", lambda: self.fmu.completedIntegratorStep())
        if terminate:
            self.terminated_at_s = self.t
        return enter, terminate

    def _event_iteration(self) -> tuple[bool, float | None, bool]:
        fmu = self.fmu
        changed, next_time, terminate = False, None, False
        for _ in range(1000):
            if self.fmi3:
                need, term, _nom, values, defined, t_next = self._call("fmi3UpdateDiscreteStates", fmu.updateDiscreteStates)
            else:
                need, term, _nom, values, defined, t_next = self._call("fmi2NewDiscreteStates", fmu.newDiscreteStates)
            changed |= values
            terminate |= term
            next_time = t_next if defined else None
            if not need or term:
                break
        else:
            raise StepError(self.name, self.t, "event iteration did not converge in 1000 rounds",
                            function="UpdateDiscreteStates", cause="chattering discrete states")
        self._time_event = next_time
        if terminate and self.terminated_at_s is None:
            self.terminated_at_s = self.t
        return changed, next_time, terminate

    def event_update(self) -> tuple[bool, float | None, bool]:
        self._call("EnterEventMode", self.fmu.enterEventMode)
        self._push_discrete()
        result = self._event_iteration()
        self._call("EnterContinuousTimeMode", self.fmu.enterContinuousTimeMode)
        return result

    def next_time_event(self) -> float | None:
        return self._time_event

    # --- co-simulation -------------------------------------------------------------------
    def do_step(self, t: float, h: float) -> None:
        self.t = t
        if self.fmi3:
            f = self._flags
            addr = ctypes.addressof(f)
            status = self._do_step3(self._inst, t, h, False, addr, addr + 1, addr + 2,
                                    ctypes.addressof(self._last_t))
            if status <= 1 and f[1]:
                # the model's normal way to say it is done: the master ends the run here
                self.terminated_at_s = self._stopped_at(t, h, self._last_t.value)
        else:
            status = self._do_step2(self._inst, t, h, 0)
            if status == 2 and self._fmi2_terminated():
                self.terminated_at_s = self._stopped_at(t, h, self._fmi2_last_successful_time(t + h))
                status = 0
        if status > 1:
            raise self._fail("fmi3DoStep" if self.fmi3 else "fmi2DoStep", t, status,
                             cause="the FMU's integrator failed (step too large for a stiff or blowing-up "
                             "model, or invalid inputs)")
        self.t = t + h

    def _fmi2_terminated(self) -> bool:
        """After fmi2Discard: did the slave stop for good (fmi2Terminated) rather than reject
        the step? An FMU without fmi2GetBooleanStatus rejected it."""
        from fmpy.fmi2 import fmi2Terminated

        said = list(self.log_lines)   # a refused status query must not bury the discard's reason
        try:
            return bool(self.fmu.getBooleanStatus(fmi2Terminated))
        except Exception:
            return False
        finally:
            self.log_lines.clear()
            self.log_lines.extend(said)

    def _fmi2_last_successful_time(self, default: float) -> float:
        from fmpy.fmi2 import fmi2LastSuccessfulTime

        try:
            return float(self.fmu.getRealStatus(fmi2LastSuccessfulTime))
        except Exception:
            return default

    @staticmethod
    def _stopped_at(t: float, h: float, reported: float) -> float:
        """Where the FMU says it stopped within [t, t + h]; a value outside (or none) means t + h."""
        return reported if math.isfinite(reported) and t <= reported <= t + h else t + h

    def get_state(self) -> Any:
        return self._call("GetFMUState", lambda: self.fmu.getFMUState() if self.fmi3 else self.fmu.getFMUstate())

    def set_state(self, state: Any) -> None:
        self.terminated_at_s = None  # back before any request to terminate
        self._call("SetFMUState", lambda: self.fmu.setFMUState(state) if self.fmi3 else self.fmu.setFMUstate(state))

    def free_state(self, state: Any) -> None:
        try:
            if self.fmi3:
                self.fmu.freeFMUState(state)
            else:
                self.fmu.freeFMUstate(state)
        except Exception:
            pass

    def close(self) -> None:
        if self.fmu is not None:
            try:
                self.fmu.terminate()
            except Exception:
                pass
            try:
                self.fmu.freeInstance()
            except Exception:
                pass
            try:
                self.fmu.freeLibrary()
            except Exception:
                pass
            self.fmu = None
        if self._own_unzip and self._unzip:
            shutil.rmtree(self._unzip, ignore_errors=True)
            self._unzip = None


def _chain(fns: list[Callable[[], None] | None]) -> Callable[[], None]:
    live = [f for f in fns if f is not None]
    if not live:
        return lambda: None
    if len(live) == 1:
        return live[0]
    first, second = live

    def both() -> None:
        first()
        second()
    return both


def model_fmu_info(model: Any, fmu_path: Path, block: str) -> FmuInfo:
    """FmuInfo of an FMU exported from a fmu_src Model; ports come from the model (exact
    feedthrough from CasADi) rather than from the XML, which may not list dependencies."""
    info = read_fmu_info(fmu_path, block)
    from ..framework.feedthrough import model_feedthrough

    feed = model_feedthrough(model)
    info.outputs = {n: Port(p.name, p.unit, p.description, feed.get(n, p.depends_on)) for n, p in info.outputs.items()}
    return info
