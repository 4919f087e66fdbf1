"""The FMU adapter: every fmpy call of featherstar's master lives here.

`read_fmu_info` parses modelDescription.xml only (no binary) for the scene checks: Float64/Real
scalar inputs and outputs with units, direct feedthrough from <ModelStructure> (an output whose
dependencies are not listed depends on every input, as the standard says), tunable and fixed
parameters, interfaces (ME, CS) and capabilities. FMI 2.0 and 3.0 are supported.

`FmuUnit` instantiates one FMU as Model Exchange ("me": the master integrates its states) or
Co-Simulation ("cs": the FMU steps itself). The calls made in the master's hot loop (set time,
states and inputs; get derivatives and outputs; doStep) go through raw ctypes prototypes on
preallocated arrays — fmpy's own wrappers cost several µs per call — and their status codes are
checked here. Every failure becomes a StepError naming the block, the FMI function and the time
(fmpy's FMICallException names neither the instance nor the time).
"""
from __future__ import annotations

import ctypes
import shutil
from collections import deque
import tempfile
from ctypes import CFUNCTYPE, c_bool, c_double, c_int, c_size_t, c_uint, c_void_p
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import fmpy
from fmpy.fmi1 import FMICallException
from fmpy.model_description import read_model_description

from .block import Port
from .errors import SceneError, StepError
from .fmi_types import port_type
from .fmu_values import PortVar, TypedAccess, ValueError_, from_carrier, to_carrier
from .units import Unit

STATUS = ["ok", "warning", "discard", "error", "fatal", "pending"]


@dataclass
class FmuInfo:
    path: Path
    fmi_version: str
    model_name: str
    inputs: dict[str, Port]
    outputs: dict[str, Port]
    parameters: dict[str, int]  # name -> value reference (scalar tunable or fixed, any type)
    vr: dict[str, int]
    has_me: bool
    has_cs: bool
    can_get_set_state: bool  # for the interface that will be used (CS if any, else ME)
    n_states: int
    n_event_indicators: int
    needs_completed_integrator_step: bool
    state_names: list[str] = field(default_factory=list)
    model_description: Any = None
    port_vars: dict[str, PortVar] = field(default_factory=dict)  # port -> variable (type, array element)
    parameter_types: dict[str, str] = field(default_factory=dict)
    arrays: dict[str, list[str]] = field(default_factory=dict)  # FMI 3 array -> its element ports


def _unit_of(var: Any) -> str:
    if getattr(var, "unit", None):
        return str(var.unit)
    dt = getattr(var, "declaredType", None)
    if dt is not None and getattr(dt, "unit", None):
        return str(dt.unit)
    return ""


def _element_names(name: str, shape: tuple[int, ...]) -> list[str]:
    """Port names of an array's elements, row-major: v[0], v[1], ... or m[0,1] for 2-D."""
    import itertools

    return [f"{name}[{','.join(map(str, index))}]" for index in itertools.product(*(range(n) for n in shape))]


def read_fmu_info(path: Path, block: str = "") -> FmuInfo:
    where = f"block '{block}': FMU '{path}'" if block else f"FMU '{path}'"
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:
        raise SceneError(f"{where}: cannot read modelDescription.xml ({exc})") from None
    version = str(md.fmiVersion)
    if not (version.startswith("2.") or version.startswith("3.")):
        raise SceneError(f"{where}: FMI {version} is not supported (FMI 2.0 and 3.0 are)")
    fmi3 = version.startswith("3.")
    inputs, outputs, params, param_types, vr, port_vars, arrays = {}, {}, {}, {}, {}, {}, {}
    for var in md.modelVariables:
        if var.causality not in ("input", "output", "parameter"):
            continue
        ptype = port_type(var.type, fmi3)
        if ptype is None:  # a Clock: not a port; nobody can connect it, so it blocks nothing
            continue
        shape = tuple(getattr(var, "shape", None) or ())
        discrete = var.variability in ("discrete", "fixed", "tunable", "constant")
        if var.causality == "parameter":
            if var.variability in ("fixed", "tunable") and not shape:
                params[var.name] = var.valueReference
                param_types[var.name] = ptype
                vr[var.name] = var.valueReference
            continue
        names = _element_names(var.name, shape) if shape else [var.name]
        if shape:
            arrays[var.name] = names
        size = len(names)
        for k, name in enumerate(names):
            vr[name] = var.valueReference
            port_vars[name] = PortVar(var.valueReference, ptype, k, size, discrete)
            port = Port(name, _unit_of(var), var.description or "", (), ptype, discrete)
            (inputs if var.causality == "input" else outputs)[name] = port

    def ports_of(name: str) -> list[str]:
        return arrays.get(name, [name] if name in inputs else [])

    all_inputs = tuple(inputs)
    listed: dict[str, tuple[str, ...]] = {}
    for unknown in md.outputs or []:
        name = unknown.variable.name
        if unknown.dependencies is None:
            deps = all_inputs
        else:
            deps = tuple(p for d in unknown.dependencies for p in ports_of(d.name))
        for port in arrays.get(name, [name]):
            listed[port] = deps
    for name, port in outputs.items():
        outputs[name] = Port(port.name, port.unit, port.description, listed.get(name, all_inputs), port.type,
                             port.discrete)
    me, cs = md.modelExchange, md.coSimulation
    iface = cs or me
    n_states = len(md.derivatives or [])
    state_names = []
    for d in md.derivatives or []:
        state = getattr(d.variable, "derivative", None)
        state_names.append(state.name if state is not None else d.variable.name)
    return FmuInfo(
        path=path, fmi_version=version, model_name=md.modelName, inputs=inputs, outputs=outputs,
        parameters=params, vr=vr, has_me=me is not None, has_cs=cs is not None,
        can_get_set_state=bool(iface and iface.canGetAndSetFMUstate),
        n_states=n_states, n_event_indicators=int(md.numberOfEventIndicators or 0),
        needs_completed_integrator_step=bool(me is not None and getattr(me, "needsCompletedIntegratorStep", False)
                                             and not getattr(me, "completedIntegratorStepNotNeeded", False)),
        state_names=state_names, model_description=md, port_vars=port_vars, parameter_types=param_types,
        arrays=arrays,
    )


_P = c_void_p  # every array argument is passed as a raw address


def _proto(dll: Any, name: str, *argtypes: Any) -> Callable[..., int]:
    address = ctypes.cast(getattr(dll, name), c_void_p).value
    return CFUNCTYPE(c_int, *argtypes)(address)


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
        self._terminated = False
        self._vr_in = (c_uint * max(len(self.input_names), 1))(*[info.vr[n] for n in self.input_names])
        self._vr_out = (c_uint * max(len(self.output_names), 1))(*[info.vr[n] for n in self.output_names])
        self.port_in = [info.port_vars[n] for n in self.input_names]
        self.port_out = [info.port_vars[n] for n in self.output_names]
        # Model Exchange: discrete inputs may be set in event mode only; the master's setters leave
        # them in inbuf and the event update pushes them (cosim.strong enters event mode for that)
        self._discrete_in = [i for i, pv in enumerate(self.port_in) if pv.discrete] if mode == "me" else []
        self.has_discrete_inputs = bool(self._discrete_in)
        self._pushed: dict[int, float] = {}
        self._array_cache: dict[int, list[Any]] = {}
        self.log_lines: deque[tuple[int, str]] = deque(maxlen=8)

    # ---------------------------------------------------------------------------------------
    def _fail(self, function: str, t: float, status: int | str, cause: str = "") -> StepError:
        label = STATUS[status] if isinstance(status, int) and 0 <= status < len(STATUS) else status
        said = self.fmu_said()
        message = f"{function} returned status {label}" + (f"; the FMU logged: {said}" if said else "")
        return StepError(self.name, t, message, function=function,
                         cause=cause or "the FMU rejected the call (invalid inputs or parameters, or the "
                         "model left its valid range)")

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
            self._call("extract", lambda: fmpy.extract(str(info.path), self._unzip))
        md = info.model_description
        iface = md.coSimulation if self.mode == "cs" else md.modelExchange
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
            self._event_iteration()
            self._call("enterContinuousTimeMode", fmu.enterContinuousTimeMode)

    def _log3(self, env, status, category, message) -> None:
        self._log(status, message)

    def _fmi2_callbacks(self) -> Any:
        """fmi2CallbackFunctions whose logger keeps the FMU's lines (fmpy's native proxy formats
        the variadic message first)."""
        from fmpy import calloc, free
        from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                               fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

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
        return _chain([self._fast_setter(fast) if fast else None, self._typed_setter(typed) if typed else None])

    def output_getter(self, idx: Sequence[int]) -> Callable[[], None]:
        fast = [i for i in idx if self.port_out[i].fast]
        typed = [i for i in idx if not self.port_out[i].fast]
        return _chain([self._fast_getter(fast) if fast else None, self._typed_getter(typed) if typed else None])

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

    def _groups(self, ports: list[PortVar], idx: Sequence[int]) -> tuple[dict[str, list[int]], dict[int, list[int]]]:
        """Port indices by call: scalars grouped by type, array elements by their variable."""
        scalars: dict[str, list[int]] = {}
        arrays: dict[int, list[int]] = {}
        for i in idx:
            pv = ports[i]
            (arrays.setdefault(pv.vr, []) if pv.size > 1 else scalars.setdefault(pv.type, [])).append(i)
        return scalars, arrays

    def _array(self, pv: PortVar) -> list[Any]:
        """The current values of an input array (its unconnected elements keep theirs)."""
        values = self._array_cache.get(pv.vr)
        if values is None:
            status, values = self._access.get(pv.type, [pv.vr], pv.size)
            if status > 1:
                raise self._fail(self._access.name("Get", pv.type), self.t, status)
            self._array_cache[pv.vr] = values
        return values

    def _typed_setter(self, idx: Sequence[int]) -> Callable[[], None]:
        scalars, arrays = self._groups(self.port_in, idx)
        access, inbuf, ports = self._access, self.inbuf, self.port_in
        calls = [(t, [ports[i].vr for i in items], items) for t, items in scalars.items()]

        def push() -> None:
            for type_, vrs, items in calls:
                status = access.set(type_, vrs, [from_carrier(type_, inbuf[i]) for i in items])
                if status > 1:
                    raise self._fail(f"{access.name('Set', type_)} (inputs)", self.t, status)
            for vr, items in arrays.items():
                pv = ports[items[0]]
                values = self._array(pv)
                for i in items:
                    values[ports[i].element] = from_carrier(pv.type, inbuf[i])
                status = access.set(pv.type, [vr], values)
                if status > 1:
                    raise self._fail(f"{access.name('Set', pv.type)} (input array)", self.t, status)
        return push

    def _typed_getter(self, idx: Sequence[int]) -> Callable[[], None]:
        scalars, arrays = self._groups(self.port_out, idx)
        access, outbuf, ports, names = self._access, self.outbuf, self.port_out, self.output_names
        calls = [(t, [ports[i].vr for i in items], items) for t, items in scalars.items()]
        calls += [(ports[items[0]].type, [vr], items) for vr, items in arrays.items()]

        def get() -> None:
            for type_, vrs, items in calls:
                size = ports[items[0]].size
                status, values = access.get(type_, vrs, len(vrs) * size)
                if status > 1:
                    raise self._fail(f"{access.name('Get', type_)} (outputs)", self.t, status)
                for j, i in enumerate(items):
                    try:
                        outbuf[i] = to_carrier(type_, values[ports[i].element if size > 1 else j])
                    except ValueError_ as exc:
                        raise StepError(self.name, self.t, f"output {names[i]}: {exc}", function=access.name("Get", type_),
                                        cause="featherstar carries integers as float64, exact to 2**53") from None
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

    def state_names(self) -> list[str]:
        return list(self.info.state_names)

    def get_event_indicators(self, address: int) -> None:
        status = self._get_z(self._inst, address, self.n_events)
        if status > 1:
            raise self._fail("GetEventIndicators", self.t, status)

    def completed_integrator_step(self) -> tuple[bool, bool]:
        return self._call("CompletedIntegratorStep", lambda: self.fmu.completedIntegratorStep())

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
                raise StepError(self.name, t + h, "the FMU asked to terminate the simulation",
                                function="fmi3DoStep", cause="the model reached the end of its validity")
        else:
            status = self._do_step2(self._inst, t, h, 0)
        if status > 1:
            raise self._fail("fmi3DoStep" if self.fmi3 else "fmi2DoStep", t, status,
                             cause="the FMU's integrator failed (step too large for a stiff or blowing-up "
                             "model, or invalid inputs)")
        self.t = t + h

    def get_state(self) -> Any:
        return self._call("GetFMUState", lambda: self.fmu.getFMUState() if self.fmi3 else self.fmu.getFMUstate())

    def set_state(self, state: Any) -> None:
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


def extract(path: Path) -> str:
    """Unzip an FMU once; several instances of the same FMU can share the folder."""
    folder = tempfile.mkdtemp(prefix="featherstar-fmu-")
    fmpy.extract(str(path), folder)
    return folder


def model_fmu_info(model: Any, fmu_path: Path, block: str) -> FmuInfo:
    """FmuInfo of an FMU exported from a fmu_src Model; ports come from the model (exact
    feedthrough from CasADi) rather than from the XML, which may not list dependencies."""
    info = read_fmu_info(fmu_path, block)
    from .blocks import model_feedthrough

    feed = model_feedthrough(model)
    info.outputs = {n: Port(p.name, p.unit, p.description, feed.get(n, p.depends_on)) for n, p in info.outputs.items()}
    return info
