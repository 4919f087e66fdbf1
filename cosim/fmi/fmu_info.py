"""What featherstar knows of an FMU before loading its binary: `read_fmu_info` parses
modelDescription.xml for the scene checks (featherstar.cosim.scene.graph) and for `FmuUnit` (featherstar.cosim.fmi.fmu_block).

Ports: inputs and outputs of every FMI type (featherstar.cosim.fmi.fmi_types), with units and variability; an
FMI 3.0 array becomes one port per element (`v[0]`, `v[1]`, ...; `m[0,1]` for 2-D, row-major),
and `arrays` lets a scene connect or record it whole. Direct feedthrough comes from
<ModelStructure> (an output whose dependencies are not listed depends on every input, as the
standard says). Parameters: scalar tunable and fixed ones, of any type. Interfaces (ME, CS) and
capabilities; continuous states (array states counted element by element).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fmpy.model_description import read_model_description

from ..errors import SceneError
from ..framework.block import Port
from .fmi_types import port_type
from .fmu_values import PortVar


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
        # only real variables can be continuous (FMI 2.0 and 3.0), whatever a file declares
        discrete = var.variability in ("discrete", "fixed", "tunable", "constant") or not ptype.startswith("Float")
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
    state_names = []
    for d in md.derivatives or []:
        state = getattr(d.variable, "derivative", None) or d.variable
        shape = tuple(getattr(state, "shape", None) or ())
        state_names.extend(_element_names(state.name, shape) if shape else [state.name])
    n_states = int(md.numberOfContinuousStates or len(state_names))
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
