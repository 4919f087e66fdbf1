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
from .units import FastPath, Unit

STATUS = ["ok", "warning", "discard", "error", "fatal", "pending"]


@dataclass
class FmuInfo:
    path: Path
    fmi_version: str
    model_name: str
    inputs: dict[str, Port]
    outputs: dict[str, Port]
    parameters: dict[str, int]  # name -> value reference (Float64/Real tunable or fixed)
    vr: dict[str, int]
    has_me: bool
    has_cs: bool
    can_get_set_state: bool  # for the interface that will be used (CS if any, else ME)
    n_states: int
    n_event_indicators: int
    needs_completed_integrator_step: bool
    state_names: list[str] = field(default_factory=list)
    model_description: Any = None


def _unit_of(var: Any) -> str:
    if getattr(var, "unit", None):
        return str(var.unit)
    dt = getattr(var, "declaredType", None)
    if dt is not None and getattr(dt, "unit", None):
        return str(dt.unit)
    return ""


def read_fmu_info(path: Path, block: str = "") -> FmuInfo:
    where = f"block '{block}': FMU '{path}'" if block else f"FMU '{path}'"
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:
        raise SceneError(f"{where}: cannot read modelDescription.xml ({exc})") from None
    version = str(md.fmiVersion)
    if not (version.startswith("2.") or version.startswith("3.")):
        raise SceneError(f"{where}: FMI {version} is not supported (FMI 2.0 and 3.0 are)")
    real_types = ("Real", "Float64")
    inputs, outputs, params, vr = {}, {}, {}, {}
    problems = []
    by_var = {}
    for var in md.modelVariables:
        if var.causality not in ("input", "output", "parameter"):
            continue
        if var.type not in real_types or (getattr(var, "dimensions", None) or []):
            if var.causality in ("input", "output"):
                problems.append(f"{where}: {var.causality} '{var.name}' is {var.type}"
                                f"{' (array)' if getattr(var, 'dimensions', None) else ''}; only scalar "
                                "Float64/Real ports are supported")
            continue
        vr[var.name] = var.valueReference
        by_var[id(var)] = var.name
        if var.causality == "parameter":
            if var.variability in ("fixed", "tunable"):
                params[var.name] = var.valueReference
        elif var.causality == "input":
            inputs[var.name] = Port(var.name, _unit_of(var), var.description or "")
    input_names = tuple(inputs)
    listed = {}
    for unknown in md.outputs or []:
        name = unknown.variable.name
        if unknown.dependencies is None:
            listed[name] = input_names
        else:
            listed[name] = tuple(d.name for d in unknown.dependencies if d.name in inputs)
    for var in md.modelVariables:
        if var.causality == "output" and var.name in vr:
            outputs[var.name] = Port(var.name, _unit_of(var), var.description or "",
                                     listed.get(var.name, input_names))
    if problems:
        raise SceneError(problems)
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
        state_names=state_names, model_description=md,
    )


_P = c_void_p  # every array argument is passed as a raw address


def _proto(dll: Any, name: str, *argtypes: Any) -> Callable[..., int]:
    address = ctypes.cast(getattr(dll, name), c_void_p).value
    return CFUNCTYPE(c_int, *argtypes)(address)


class FmuUnit(Unit):
    """One FMU instance, Model Exchange (`mode="me"`) or Co-Simulation (`mode="cs"`)."""

    def __init__(self, name: str, info: FmuInfo, parameters: dict[str, float], mode: str,
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

    # ---------------------------------------------------------------------------------------
    def _fail(self, function: str, t: float, status: int | str, cause: str = "") -> StepError:
        label = STATUS[status] if isinstance(status, int) and 0 <= status < len(STATUS) else status
        return StepError(self.name, t, f"{function} returned status {label}", function=function,
                         cause=cause or "the FMU rejected the call (invalid inputs or parameters, or the "
                         "model left its valid range)")

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
            self._call("instantiate", lambda: self.fmu.instantiate())
        self._bind()
        fmu = self.fmu
        if self.parameters:
            vrs = [info.parameters[k] for k in self.parameters]
            vals = [float(v) for v in self.parameters.values()]
            setter = fmu.setFloat64 if self.fmi3 else fmu.setReal
            self._call("set parameters", lambda: setter(vrs, vals))
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

    def _log3(self, env, status, category, message) -> None:  # FMU log: keep errors for messages
        if status >= 2:
            self.last_message = (message or b"").decode("utf-8", "replace")

    last_message = ""

    def _bind(self) -> None:
        dll = self.fmu.dll
        inst = self.fmu.component
        self._inst = inst
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

    def output_getter(self, idx: Sequence[int]) -> Callable[[], None]:
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
                             cause=self.last_message or "the FMU's integrator failed (step too large for a "
                             "stiff or blowing-up model, or invalid inputs)")
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


def extract(path: Path) -> str:
    """Unzip an FMU once; several instances of the same FMU can share the folder."""
    folder = tempfile.mkdtemp(prefix="featherstar-fmu-")
    fmpy.extract(str(path), folder)
    return folder


def model_fmu_info(model: Any, fmu_path: Path, block: str) -> FmuInfo:
    """FmuInfo of an FMU exported from a fmu_src Model; ports come from the model (exact
    feedthrough from CasADi) rather than from the XML, which may not list dependencies."""
    info = read_fmu_info(fmu_path, block)
    from .feedthrough import model_feedthrough

    feed = model_feedthrough(model)
    info.outputs = {n: Port(p.name, p.unit, p.description, feed.get(n, p.depends_on)) for n, p in info.outputs.items()}
    return info
