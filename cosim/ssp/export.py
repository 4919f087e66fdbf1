"""A scene -> an SSP 1.0 package (.ssp): `export_ssp(scene, out)`, `featherstar export-ssp`.

The package is a zip holding SystemStructure.ssd and, under resources/, one FMU per FMU block:
a model block's FMU is built (FMI 3.0, or 2.0 for older importers), an FMU file is copied. In
SystemStructure.ssd every FMU block is an ssd:Component with its ports as connectors (with their
units, defined in ssd:Units by SI base units; none on a waived connection's ends) and the
parameter values the run would use as an inline ssv:ParameterSet; connections between FMU
blocks are ssd:Connections.

For other tools the package is FMUs only where it can be: a Python block that drives an FMU
input and offers an FMU of itself (`fmu_stand_in()`: the stroke controller, constants; built by
fmu_src like the others) is an ssd:Component too, and ssd:DefaultExperiment gives the run's
length (a run measured in stroke periods: periods x period). Ecos and libcosim run such a
package as it is (tests/cosim/test_ssp_peers.py). With `system_outputs`, the recorded signals
(recorders' and metrics') of components are also system output connectors named "block.port",
each fed by an ssd:Connection without endElement, as SSP connects system connectors; Ecos 0.7.2
and libcosim 0.0.6 refuse any such connection ("No element named: feather", "No such node
(<xmlattr>.endElement)"), so it is off by default.

Every featherstar block (stand-ins included, as they were: a stroke, not its FMU), the master
and metrics settings are written in an ssc:Annotation of type `org.featherstar.scene` (JSON),
so `featherstar run x.ssp` (featherstar.cosim.ssp.read) puts the same scene back together.
Blocks without an FMU (gains, recorders, Python blocks, a sampled stroke command) exist only
there; where one drives an FMU input the system gets an input connector named "block.port" (an
output connector where an FMU output drives one), which other tools must supply their own way.
"""
from __future__ import annotations

import dataclasses
import json
import shutil
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path
from typing import Any, Callable, Mapping

from ...fmu_src.model import Model
from ...fmu_src.si_units import base_unit
from ..errors import SceneError
from ..scene.block_kind import ResolvedBlock
from ..scene.blocks import Gain
from ..scene.data import MasterSpec, MetricsSpec, Scene
from ..scene.graph import plan as make_plan
from ..scene.plan import Plan
from ..scene.specs import PortRef
from .read import FEATHERSTAR_ANNOTATION, FMU_TYPE, NS, SSD_NAME

#: Every component's parameter set has this name: Ecos applies the sets of one name, chosen at
#: initialization (`EcosSimulation.init(parameter_set="initialValues")`); others ignore the name.
PARAMETER_SET_NAME = "initialValues"

for _prefix, _uri in NS.items():
    ET.register_namespace(_prefix, _uri)


def _q(prefix: str, tag: str) -> str:
    return f"{{{NS[prefix]}}}{tag}"


def _number(value: float) -> str:
    return repr(float(value))


def export_ssp(scene: Scene, out: Path, overrides: Mapping[str, Any] | None = None, *,
               fmi_version: int = 3, system_outputs: bool = False,
               progress: Callable[[str], None] | None = None) -> Path:
    """Write `scene` (with "block.key" overrides) as the SSP package `out`; returns its path.
    `system_outputs` adds the recorded signals as system output connectors (module docstring).
    `progress` hears about each FMU as it is built or copied (a build can take a minute).

    Raises SceneError for a scene that does not validate, BuildError when an FMU cannot be built.
    """
    scene = scene.with_overrides(overrides)
    plan = make_plan(scene)
    fmu_blocks = [name for name in scene.block_names
                  if plan.blocks[name].model is not None or plan.blocks[name].fmu_path is not None]
    if not fmu_blocks:
        raise SceneError(f"scene '{scene.name}' has no FMU blocks: an SSP package would hold no component")
    stand_ins = _stand_ins(scene, plan, set(fmu_blocks))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="featherstar-ssp-") as tmp:
        work = Path(tmp)
        sources = {}
        for name in fmu_blocks:
            if progress is not None:
                progress(f"FMU of block '{name}'")
            sources[name] = _fmu_file(plan.blocks[name], work, fmi_version)
        from ...fmu_src.export import build_fmu

        for name, (model, _) in stand_ins.items():
            if progress is not None:
                progress(f"FMU standing in for block '{name}' ({model.name})")
            sources[name] = _copy_fmu(build_fmu(model, fmi_version=fmi_version), work, name)
        ssd = _system_structure(scene, plan, sources, {n: values for n, (_, values) in stand_ins.items()},
                                system_outputs)
        (work / SSD_NAME).write_text(ssd, encoding="utf-8")
        partial = out.with_name(f".{out.name}.part")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.write(work / SSD_NAME, SSD_NAME)
            for archived in sorted(sources.values()):
                archive.write(work / archived, archived)
        partial.replace(out)
    return out


def _stand_ins(scene: Scene, plan: Plan, fmu_blocks: set[str]) -> dict[str, tuple[Model, dict[str, float]]]:
    """{block: (model, parameter values)} of the Python blocks that drive an FMU input and offer
    an FMU of themselves."""
    from ...fmu_src.catalog import build_model

    # a gain that feeds FMUs only is a transformed connection: what drives it drives those FMUs
    feeds_fmus = {name for name in scene.block_names if isinstance(plan.blocks[name].obj, Gain)
                  and _drives_only(scene, name, fmu_blocks)}
    drives_fmu = {c.src.block for c in scene.connections if c.dst.block in fmu_blocks | feeds_fmus}
    out = {}
    for name in scene.block_names:
        offer = getattr(plan.blocks[name].obj, "fmu_stand_in", None)
        stand_in = offer() if name in drives_fmu and offer is not None else None
        if stand_in is not None:
            kind, options, values = stand_in
            out[name] = (build_model(kind, options), dict(values))
    return out


def _linear_gains(scene: Scene, plan: Plan, in_ssp: set[str]) -> dict[str, tuple[PortRef, list[PortRef]]]:
    """{gain: (its driver, the inputs it drives)} of the gain blocks between components only:
    each is an ssc:LinearTransformation on a connection of those components."""
    out = {}
    for name in scene.block_names:
        if not isinstance(plan.blocks[name].obj, Gain):
            continue
        into = [c.src for c in scene.connections if c.dst.block == name]
        if into and into[0].block in in_ssp and _drives_only(scene, name, in_ssp):
            out[name] = (into[0], [c.dst for c in scene.connections if c.src.block == name])
    return out


def _drives_only(scene: Scene, block: str, targets: set[str]) -> bool:
    """Does `block` drive something, and only blocks in `targets`?"""
    driven = {c.dst.block for c in scene.connections if c.src.block == block}
    return bool(driven) and driven <= targets


def _fmu_file(rb: ResolvedBlock, work: Path, fmi_version: int) -> str:
    """Put the block's FMU under work/resources/; returns its path inside the package."""
    if rb.model is not None:
        from ...fmu_src.export import build_fmu

        return _copy_fmu(build_fmu(rb.model, fmi_version=fmi_version), work, rb.name)
    return _copy_fmu(rb.fmu_path, work, rb.name)


def _copy_fmu(path: Path, work: Path, name: str) -> str:
    target = work / "resources" / f"{name}.fmu"
    target.parent.mkdir(exist_ok=True)
    shutil.copyfile(path, target)
    return f"resources/{target.name}"


def _parameter_values(rb: ResolvedBlock) -> dict[str, float]:
    """What the run would set: every model parameter (defaults under the scene's values); for an
    FMU file, the values the scene sets (its other start values stay in the FMU)."""
    if rb.model is None:
        return dict(rb.parameters)
    values = rb.model.default_parameters()
    values.update(rb.parameters)
    return values


def _system_structure(scene: Scene, plan: Plan, sources: dict[str, str],
                      stand_ins: dict[str, dict[str, float]], system_outputs: bool) -> str:
    blocks = plan.blocks
    root = ET.Element(_q("ssd", "SystemStructureDescription"), {"version": "1.0", "name": scene.name})
    system = ET.SubElement(root, _q("ssd", "System"), {"name": scene.name})
    if scene.description:
        system.set("description", scene.description)
    in_ssp = set(sources)
    system_connectors: list[tuple[str, str]] = []  # (name, kind)
    ssd_connections: list[dict[str, str]] = []
    featherstar_connections: list[str] = []
    gains = _linear_gains(scene, plan, in_ssp)
    transformed: dict[str, tuple[float, float]] = {}   # "src -> dst" between components -> (factor, offset)
    for name, (src, dsts) in gains.items():
        for dst in dsts:
            transformed[f"{src} -> {dst}"] = (blocks[name].obj.gain, blocks[name].obj.offset)
            ssd_connections.append({"startElement": src.block, "startConnector": src.port,
                                    "endElement": dst.block, "endConnector": dst.port})
    for connection in scene.connections:
        src, dst = connection.src, connection.dst
        if src.block in gains or dst.block in gains:   # written as a transformed connection above
            featherstar_connections.append(str(connection))
        elif src.block in in_ssp and dst.block in in_ssp:
            ssd_connections.append({"startElement": src.block, "startConnector": src.port,
                                    "endElement": dst.block, "endConnector": dst.port})
        elif dst.block in in_ssp:  # a featherstar block drives an FMU input
            system_connectors.append((str(src), "input"))
            ssd_connections.append({"startConnector": str(src), "endElement": dst.block, "endConnector": dst.port})
        elif src.block in in_ssp:  # an FMU output drives a featherstar block
            system_connectors.append((str(dst), "output"))
            ssd_connections.append({"startElement": src.block, "startConnector": src.port, "endConnector": str(dst)})
        else:
            featherstar_connections.append(str(connection))
    for ref in plan.requested if system_outputs else ():   # for tools that record system outputs
        if ref.block in in_ssp:
            system_connectors.append((str(ref), "output"))
            ssd_connections.append({"startElement": ref.block, "startConnector": ref.port, "endConnector": str(ref)})
    if system_connectors:
        connectors = ET.SubElement(system, _q("ssd", "Connectors"))
        for name, kind in dict.fromkeys(system_connectors):
            connector = ET.SubElement(connectors, _q("ssd", "Connector"), {"name": name, "kind": kind})
            ET.SubElement(connector, _q("ssc", "Real"))

    elements = ET.SubElement(system, _q("ssd", "Elements"))
    # a waived connection joins ports whose units differ on purpose, and a gain may change the
    # unit (deg -> rad): SSP tools would convert there
    unitless = {(ref.block, ref.port) for c in scene.unit_waivers for ref in (c.src, c.dst)}
    unitless |= {(ref.block, ref.port) for src, dsts in gains.values() for ref in (src, *dsts)}
    units: set[str] = set()
    for name, source in sources.items():
        units |= _component(elements, blocks[name], source, stand_ins.get(name), unitless)
    if ssd_connections:
        connections = ET.SubElement(system, _q("ssd", "Connections"))
        for attributes in ssd_connections:
            connection = ET.SubElement(connections, _q("ssd", "Connection"), attributes)
            key = f"{attributes.get('startElement')}.{attributes['startConnector']} -> " \
                  f"{attributes.get('endElement')}.{attributes['endConnector']}"
            if key in transformed:
                factor, offset = transformed[key]
                ET.SubElement(connection, _q("ssc", "LinearTransformation"),
                              {"factor": _number(factor), "offset": _number(offset)})

    annotations = ET.SubElement(system, _q("ssd", "Annotations"))
    annotation = ET.SubElement(annotations, _q("ssc", "Annotation"), {"type": FEATHERSTAR_ANNOTATION})
    ET.SubElement(annotation, _q("fs", "Scene"), {"format": "json"}).text = json.dumps(
        _featherstar_part(scene, set(sources) - set(stand_ins), featherstar_connections, sorted(stand_ins),
                          sorted(transformed)),
        indent=1, sort_keys=True)
    if units:
        definitions = ET.SubElement(root, _q("ssd", "Units"))
        for unit in sorted(units):
            ET.SubElement(ET.SubElement(definitions, _q("ssc", "Unit"), {"name": unit}), _q("ssc", "BaseUnit"),
                          {k: str(v) for k, v in (base_unit(unit) or {}).items()})
    # the run's length, also when given in stroke periods (the annotation keeps `periods`)
    ET.SubElement(root, _q("ssd", "DefaultExperiment"), {"startTime": "0.0", "stopTime": _number(plan.t_end_s)})
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode")


def _component(elements: ET.Element, rb: ResolvedBlock, source: str, stand_in: dict[str, float] | None,
               unitless: set[tuple[str, str]]) -> set[str]:
    """Write the component; returns the units its connectors declare (those with SI base units)."""
    component = ET.SubElement(elements, _q("ssd", "Component"),
                              {"name": rb.name, "type": FMU_TYPE, "source": source})
    if rb.spec.description:
        component.set("description", rb.spec.description)
    connectors = ET.SubElement(component, _q("ssd", "Connectors"))
    values = _parameter_values(rb) if stand_in is None else stand_in
    units = set()
    for kind, ports in (("input", rb.inputs), ("output", rb.outputs), ("parameter", dict.fromkeys(values))):
        for port in ports:
            connector = ET.SubElement(connectors, _q("ssd", "Connector"), {"name": port, "kind": kind})
            real = ET.SubElement(connector, _q("ssc", "Real"))
            unit = getattr(ports[port], "unit", "").strip() if kind != "parameter" else ""
            if unit and (rb.name, port) not in unitless and base_unit(unit) is not None:
                real.set("unit", unit)
                units.add(unit)
    if not values:
        return units
    bindings = ET.SubElement(component, _q("ssd", "ParameterBindings"))
    binding = ET.SubElement(bindings, _q("ssd", "ParameterBinding"))
    holder = ET.SubElement(binding, _q("ssd", "ParameterValues"))
    parameter_set = ET.SubElement(holder, _q("ssv", "ParameterSet"), {"version": "1.0", "name": PARAMETER_SET_NAME})
    parameters = ET.SubElement(parameter_set, _q("ssv", "Parameters"))
    for name, value in values.items():
        parameter = ET.SubElement(parameters, _q("ssv", "Parameter"), {"name": name})
        ET.SubElement(parameter, _q("ssv", "Real"), {"value": _number(value)})
    return units


def _featherstar_part(scene: Scene, in_ssp: set[str], connections: list[str], stand_ins: list[str],
                      transformed: list[str]) -> dict[str, Any]:
    """What only featherstar reads back: its own blocks (and which components stand in for some
    of them, which ssd:Connections are gains), their connections, master and metrics."""
    blocks = {}
    for block in scene.blocks:
        if block.name in in_ssp:
            continue
        table = {"kind": block.kind, **block.settings.to_plain()}
        if block.description:
            table["description"] = block.description
        blocks[block.name] = table
    # Each block kind applies --set values its own way (a stroke's period_s scales its times):
    # they go back as the same overrides, applied to the same settings.
    overrides = {f"{b.name}.{key}": value for b in scene.blocks if b.name not in in_ssp
                 for key, value in b.overrides.to_plain().items()}

    def changed(spec: Any, default: Any) -> dict[str, Any]:
        return {k: v for k, v in dataclasses.asdict(spec).items() if v != getattr(default, k)}

    master = changed(scene.master, MasterSpec())
    master["t_end_s"] = scene.master.t_end_s   # 0 = `periods` rules, whatever DefaultExperiment says
    return {
        "description": scene.description,
        "blocks": blocks,
        "stand_ins": stand_ins,
        "transformed": transformed,
        "connections": connections,
        "overrides": overrides,
        "aliases": scene.aliases.to_plain(),
        **({"units": {"waive": [str(c) for c in scene.unit_waivers]}} if scene.unit_waivers else {}),
        "master": master,
        "metrics": changed(scene.metrics, MetricsSpec()),
    }

