"""An SSP 1.0 package (.ssp) -> scene data: `read_ssp(path)`, which `load_scene` turns into a Scene
for .ssp files (this module does not import featherstar.cosim.scene.data: the door opens one way).

What is mapped: the system's ssd:Components of type application/x-fmu-sharedlibrary (FMI 2.0
or 3.0 FMUs in the package) become `fmu` blocks; ssd:Connections between their connectors
become connections; parameter values bound inline (ssd:ParameterValues) or from .ssv files in the
package, at system level ("component.parameter") or component level, become the blocks'
parameters; ssd:DefaultExperiment's stopTime becomes master.t_end_s. A package written by
`featherstar export-ssp` also carries an `org.featherstar.scene` annotation with the
blocks SSP has no component type for, the master and metrics settings; system connectors named
"block.port" connect those blocks. System outputs fed by components are recorded.

A connection between two components with an ssc:LinearTransformation (y = factor x + offset)
becomes a `gain` block between them (named `transform_<n>`, its ports without units, so the plan
notes the connection as not unit-checked), unless featherstar's annotation says the
transformation is one of its own gain blocks (`transformed`), which the annotation wires.
Components the annotation lists as `stand_ins` (a stroke's FMU) are replaced by its blocks.

What featherstar cannot map is refused, naming the element: nested systems, signal
dictionaries, non-FMU components, parameter mappings, other connection transformations
(boolean, integer, enumeration mappings) and linear ones on system connectors, connections
between connectors whose declared units differ (featherstar converts no unit), non-numeric
parameter values, system inputs nothing drives, a start time other than 0. Other annotations and
geometry are ignored.
"""
from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import shutil
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path, PurePosixPath
from typing import Any

from ..errors import SceneError
from ..fmi.bounded_zip import extract_bounded
from .code_refs import refuse_foreign_code

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "ssm": "http://ssp-standard.org/SSP1/SystemStructureParameterMapping",
    "ssb": "http://ssp-standard.org/SSP1/SystemStructureSignalDictionary",
    "fs": "https://featherstar.org/ssp/1",
}
SSD_NAME = "SystemStructure.ssd"
FMU_TYPE = "application/x-fmu-sharedlibrary"
PARAMETER_SET_TYPE = "application/x-ssp-parameter-set"
FEATHERSTAR_ANNOTATION = "org.featherstar.scene"
#: The recorder that records the system's outputs (connectors of kind output fed by components).
OUTPUTS_RECORDER = "system_outputs"

#: The block kinds the annotation may hold: FMUs are the package's components, never an FMU file
#: elsewhere; a python block's code reference is judged by featherstar.cosim.ssp.code_refs
#: (featherstar's own blocks, or anything with --allow-code).
ANNOTATION_KINDS = ("stroke", "constant", "gain", "recorder", "python")
#: What each key of featherstar's annotation holds (a package is data: anything else is refused).
_ANNOTATION_TYPES = {"description": str, "blocks": dict, "connections": list, "overrides": dict, "aliases": dict,
                     "units": dict, "master": dict, "metrics": dict, "stand_ins": list, "transformed": list}
_JSON_NAME = {str: "string", dict: "object", list: "array"}

_PREFIX_OF = {uri: prefix for prefix, uri in NS.items()}
_IGNORED = {"ElementGeometry", "ConnectorGeometry", "ConnectionGeometry", "GraphicalElements", "Units",
            "Enumerations", "Annotations"}


def _q(prefix: str, tag: str) -> str:
    return f"{{{NS[prefix]}}}{tag}"


def _name(element: ET.Element) -> str:
    """'ssd:Connection' for {uri-of-ssd}Connection: how the SSP standard names elements."""
    if not element.tag.startswith("{"):
        return element.tag
    uri, _, local = element.tag[1:].partition("}")
    return f"{_PREFIX_OF.get(uri, uri)}:{local}"


def is_ssp(path: str | Path) -> bool:
    return str(path).lower().endswith(".ssp")


def read_ssp(path: str | Path, *, allow_code: bool = False) -> tuple[dict[str, Any], dict[str, Any]]:
    """The scene an SSP package describes, as scene data (featherstar.cosim.scene.data.scene_from_dict) and the
    overrides its parameter bindings make. Raises SceneError naming what cannot be mapped.

    A package is data: its featherstar annotation may use featherstar's block kinds, featherstar's own
    block classes and the FMUs inside it; any other reference to Python code (featherstar.cosim.ssp.
    code_refs) is refused unless `allow_code` (`featherstar run x.ssp --allow-code`). The package is
    unpacked within bounds (featherstar.cosim.fmi.bounded_zip) and kept in the cache only once read."""
    path = Path(path)
    where = f"SSP package '{path}'"
    if not path.is_file():
        raise SceneError(f"{where}: no such file")
    with open(path, "rb") as fh:
        digest = hashlib.file_digest(fh, "sha256").hexdigest()[:16]
    target = ssp_cache() / f"{path.stem}-{digest}"
    if target.is_dir():   # unpacked and read before: the cache holds only packages that were read
        return _read_folder(target, target, where, allow_code)
    ssp_cache().mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=ssp_cache()))
    staging = work / "package"
    try:
        extract_bounded(path, staging, where, quota=(ssp_cache(), ssp_cache_quota_bytes()))
        data, overrides = _read_folder(staging, target, where, allow_code)
        try:
            os.replace(staging, target)
        except OSError:
            if not target.is_dir():  # not a concurrent reader that got there first
                raise
    finally:   # a refused package leaves nothing in the cache
        shutil.rmtree(work, ignore_errors=True)
    return data, overrides


def ssp_cache() -> Path:
    """Where packages are unpacked (FMU paths must stay valid after read_ssp: a run loads them later)."""
    from ...fmu_src.export import cache_dir

    return cache_dir() / "ssp"


def ssp_cache_quota_bytes() -> int:
    """What the package cache may hold in all: $FEATHERSTAR_SSP_CACHE_MB, else 4096 MB."""
    text = os.environ.get("FEATHERSTAR_SSP_CACHE_MB", "4096")
    try:
        return int(float(text) * (1 << 20))
    except ValueError:
        raise SceneError(f"FEATHERSTAR_SSP_CACHE_MB = '{text}' is not a number of MB") from None


def _read_folder(folder: Path, placed: Path, where: str, allow_code: bool) -> tuple[dict[str, Any], dict[str, Any]]:
    """Read the package unpacked in `folder`; its files are named as they will lie in `placed`."""
    ssd_path = folder / SSD_NAME
    if not ssd_path.is_file():
        raise SceneError(f"{where}: no {SSD_NAME} at the top of the package")
    try:
        root = ET.parse(ssd_path).getroot()
    except ET.ParseError as exc:
        raise SceneError(f"{where}: {SSD_NAME} is not well-formed XML ({exc})") from None
    reader = _SystemReader(folder, placed, where)
    data, overrides = reader.read(root)
    if not allow_code:   # first: that a package names code says more than what else is wrong with it
        refuse_foreign_code(reader.annotation, where)
    if reader.problems:
        raise SceneError(reader.problems, data.get("name", folder.stem))
    return data, overrides


class _SystemReader:
    """Reads SystemStructure.ssd into scene data, collecting every problem (`problems`)."""

    def __init__(self, folder: Path, placed: Path, where: str) -> None:
        self.folder = folder
        self.placed = placed
        self.where = where
        self.problems: list[str] = []
        self.annotation: Any = None  # the featherstar annotation as written (JSON), judged whole
        self.units: dict[tuple[str | None, str], str] = {}   # (element or None, connector) -> declared unit
        self.transformed: set[str] = set()

    def refuse(self, message: str) -> None:
        self.problems.append(message)

    def read(self, root: ET.Element) -> tuple[dict[str, Any], dict[str, Any]]:
        if root.tag != _q("ssd", "SystemStructureDescription"):
            self.refuse(f"the root element of {SSD_NAME} is {_name(root)}, not ssd:SystemStructureDescription "
                        f"(namespace {NS['ssd']})")
            return {}, {}
        data: dict[str, Any] = {"name": root.get("name") or "ssp"}
        systems = root.findall(_q("ssd", "System"))
        if len(systems) != 1:
            self.refuse(f"ssd:SystemStructureDescription '{data['name']}' must hold one ssd:System, not {len(systems)}")
            return data, {}
        t_end_s = self._default_experiment(root.find(_q("ssd", "DefaultExperiment")))
        data, overrides = self._system(systems[0], data)
        if t_end_s is not None:
            data.setdefault("master", {}).setdefault("t_end_s", t_end_s)
        return data, overrides

    def _default_experiment(self, experiment: ET.Element | None) -> float | None:
        if experiment is None:
            return None
        start = self._float(experiment, "startTime", "ssd:DefaultExperiment", 0.0)
        if start not in (None, 0.0):
            self.refuse(f"ssd:DefaultExperiment startTime = {experiment.get('startTime')}: featherstar runs "
                        "start at t = 0")
        stop = self._float(experiment, "stopTime", "ssd:DefaultExperiment", None)
        return stop

    def _float(self, element: ET.Element, attribute: str, what: str, default: float | None) -> float | None:
        text = element.get(attribute)
        if text is None:
            return default
        try:
            return float(text)
        except ValueError:
            self.refuse(f"{what} {attribute} = '{text}' is not a number")
            return None

    # --- the system ------------------------------------------------------------------------
    def _system(self, system: ET.Element, data: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
        label = f"ssd:System '{system.get('name', '')}'"
        data["name"] = data["name"] or system.get("name")
        if system.get("description"):
            data["description"] = system.get("description")
        extra, overrides = self._annotation(system.find(_q("ssd", "Annotations")))
        blocks: dict[str, dict[str, Any]] = {}
        parameters: dict[str, dict[str, float]] = {}
        connectors: dict[str, str] = {}
        for child in system:
            local = _name(child)
            if local == "ssd:Connectors":
                connectors = self._connectors(child, label)
            elif local == "ssd:Elements":
                for element in child:
                    self._element(element, blocks, parameters)
            elif local in ("ssd:ParameterBindings", "ssd:Connections") or local.split(":")[-1] in _IGNORED:
                continue
            else:
                self.refuse(f"{local} in {label}: featherstar cannot map it (only components, connectors, "
                            "connections and parameter bindings)")
        for name, value in self._bindings(system.find(_q("ssd", "ParameterBindings")), label).items():
            component, dot, parameter = name.partition(".")
            if not dot or component not in blocks:
                self.refuse(f"parameter '{name}' bound in {label} names no component's parameter "
                            f"(write 'component.parameter'; components: {', '.join(blocks) or 'none'})")
                continue
            parameters.setdefault(component, {})[parameter] = value
        for component, values in parameters.items():
            if component in blocks and values:
                blocks[component]["parameters"] = values
        annotated = bool(extra)
        own_blocks = extra.pop("blocks", {})
        if not (isinstance(own_blocks, dict) and all(isinstance(t, dict) for t in own_blocks.values())):
            self.refuse(f"ssc:Annotation '{FEATHERSTAR_ANNOTATION}': 'blocks' must map block names to tables")
            own_blocks = {}
        for name, table in list(own_blocks.items()):
            if table.get("kind") not in ANNOTATION_KINDS:   # a package's FMUs are its components
                self.refuse(f"block '{name}' of the {FEATHERSTAR_ANNOTATION} annotation has kind "
                            f"{table.get('kind')!r:.40}: its blocks may be {', '.join(ANNOTATION_KINDS)} "
                            "(an FMU is an ssd:Component of the package, never a file elsewhere)")
                del own_blocks[name]
        # components that stand in for featherstar blocks (a stroke's FMU, for other tools):
        # featherstar runs the blocks themselves
        stand_ins = self._names(extra.pop("stand_ins", []), "stand_ins")
        # connections whose ssc:LinearTransformation is a gain block of the annotation (wired there)
        self.transformed = self._names(extra.pop("transformed", []), "transformed")
        for name in own_blocks:
            if name in blocks and name not in stand_ins:
                self.refuse(f"block '{name}' of the {FEATHERSTAR_ANNOTATION} annotation has the name of an ssd:Component")
        for name in sorted(stand_ins - set(own_blocks) - set(blocks)):
            self.refuse(f"the {FEATHERSTAR_ANNOTATION} annotation's stand-in '{name}' is no ssd:Component of the "
                        "system with a block of that name in the annotation")
        blocks.update(own_blocks)
        raw_connections = extra.pop("connections", [])
        connections = list(raw_connections) if self._names(raw_connections, "connections") else []
        outputs = []
        for connection in system.iterfind(f"{_q('ssd', 'Connections')}/{_q('ssd', 'Connection')}"):
            mapped = self._connection(connection, blocks, own_blocks, connectors)
            if isinstance(mapped, tuple):
                outputs.append(mapped[0])
            elif isinstance(mapped, list):
                connections.extend(mapped)
            elif mapped:
                connections.append(mapped)
        # featherstar's own package names its recorders; the system outputs repeat their signals
        if outputs and OUTPUTS_RECORDER not in blocks and not annotated:
            blocks[OUTPUTS_RECORDER] = {"kind": "recorder", "signals": outputs}
        data.update(extra)
        data["blocks"] = blocks
        data["connections"] = connections
        return data, overrides

    def _names(self, value: Any, key: str) -> set[str]:
        if isinstance(value, list) and all(isinstance(v, str) for v in value):
            return set(value)
        self.refuse(f"ssc:Annotation '{FEATHERSTAR_ANNOTATION}': '{key}' must be a list of strings, not {value!r:.80}")
        return set()

    def _annotation(self, annotations: ET.Element | None) -> tuple[dict[str, Any], dict[str, Any]]:
        if annotations is None:
            return {}, {}
        for annotation in annotations.iterfind(_q("ssc", "Annotation")):
            if annotation.get("type") != FEATHERSTAR_ANNOTATION:
                continue  # other tools' annotations are theirs
            content = annotation.find(_q("fs", "Scene"))
            try:
                extra = json.loads(content.text or "") if content is not None else None
            except json.JSONDecodeError as exc:
                self.refuse(f"ssc:Annotation '{FEATHERSTAR_ANNOTATION}': fs:Scene is not valid JSON ({exc})")
                return {}, {}
            self.annotation = copy.deepcopy(extra)
            if not isinstance(extra, dict):
                self.refuse(f"ssc:Annotation '{FEATHERSTAR_ANNOTATION}' must hold an fs:Scene JSON object")
                return {}, {}
            wrong = [f"'{key}' must be a JSON {_JSON_NAME[kind]}, not {extra[key]!r:.80}" for key, kind in _ANNOTATION_TYPES.items()
                     if key in extra and not isinstance(extra[key], kind)]
            blocks = extra.get("blocks") if isinstance(extra.get("blocks"), dict) else {}
            wrong += [f"block '{name}' must be a JSON object" for name, block in blocks.items() if not isinstance(block, dict)]
            overrides = extra.get("overrides") if isinstance(extra.get("overrides"), dict) else {}
            wrong += [f"override '{key}' must be a number, a string or a boolean" for key, value in overrides.items()
                      if not isinstance(value, (str, int, float, bool))]
            if wrong:
                self.refuse(f"ssc:Annotation '{FEATHERSTAR_ANNOTATION}': {'; '.join(wrong)}")
                return {}, {}
            return extra, dict(extra.pop("overrides", {}))
        return {}, {}

    def _connectors(self, connectors: ET.Element, label: str) -> dict[str, str]:
        kinds = {}
        for connector in connectors.iterfind(_q("ssd", "Connector")):
            name, kind = connector.get("name"), connector.get("kind")
            if not name or kind not in ("input", "output", "parameter", "calculatedParameter", "inout"):
                self.refuse(f"ssd:Connector '{name}' of {label} needs a name and a kind "
                            "(input, output, parameter, calculatedParameter)")
                continue
            kinds[name] = kind
            self._note_unit(None, connector)
        return kinds

    def _note_unit(self, element: str | None, connector: ET.Element) -> None:
        for typed in connector:
            if typed.get("unit"):
                self.units[(element, connector.get("name", ""))] = typed.get("unit", "")

    # --- components ------------------------------------------------------------------------
    def _element(self, element: ET.Element, blocks: dict[str, Any], parameters: dict[str, Any]) -> None:
        kind, name = _name(element), element.get("name", "")
        if kind != "ssd:Component":
            self.refuse(f"{kind} '{name}': featherstar maps a flat system of FMU components only "
                        "(no nested systems or signal dictionaries)")
            return
        label = f"ssd:Component '{name}'"
        if not name or "." in name:
            self.refuse(f"{label}: a component needs a name without '.'")
            return
        component_type = element.get("type", FMU_TYPE)
        if component_type != FMU_TYPE:
            self.refuse(f"{label} has type '{component_type}': featherstar runs FMU components ({FMU_TYPE}) only")
            return
        source = self._package_file(element.get("source"), f"{label} source")
        if source is None:
            return
        block: dict[str, Any] = {"kind": "fmu", "fmu": str(self.placed / source.relative_to(self.folder))}
        if element.get("description"):
            block["description"] = element.get("description")
        for child in element:
            local = _name(child)
            if local == "ssd:ParameterBindings":
                parameters.setdefault(name, {}).update(self._bindings(child, label))
            elif local == "ssd:Connectors":
                for connector in child.iterfind(_q("ssd", "Connector")):
                    self._note_unit(name, connector)
            elif local.split(":")[-1] not in _IGNORED:
                self.refuse(f"{local} in {label}: featherstar cannot map it")
        blocks[name] = block

    def _package_file(self, reference: str | None, what: str) -> Path | None:
        if not reference:
            self.refuse(f"{what} is missing")
            return None
        relative = PurePosixPath(reference.removeprefix("./"))
        if ":" in reference or relative.is_absolute() or ".." in relative.parts:
            self.refuse(f"{what} '{reference}' is not a file inside the package")
            return None
        path = self.folder / relative
        if not path.is_file():
            self.refuse(f"{what} '{reference}' is not in the package")
            return None
        return path

    # --- parameters ------------------------------------------------------------------------
    def _bindings(self, bindings: ET.Element | None, label: str) -> dict[str, float]:
        values: dict[str, float] = {}
        if bindings is None:
            return values
        for binding in bindings.iterfind(_q("ssd", "ParameterBinding")):
            what = f"ssd:ParameterBinding of {label}"
            if binding.get("type", PARAMETER_SET_TYPE) != PARAMETER_SET_TYPE:
                self.refuse(f"{what} has type '{binding.get('type')}': only {PARAMETER_SET_TYPE} (.ssv) is read")
                continue
            if binding.get("sourceBase", "SSD") != "SSD":
                self.refuse(f"{what} has sourceBase = '{binding.get('sourceBase')}': only files of the package "
                            "(sourceBase = SSD) are read")
                continue
            if binding.find(_q("ssd", "ParameterMapping")) is not None:
                self.refuse(f"ssd:ParameterMapping in the {what}: parameter mappings are not supported")
                continue
            inline = binding.find(f"{_q('ssd', 'ParameterValues')}/{_q('ssv', 'ParameterSet')}")
            if inline is None and binding.get("source"):
                path = self._package_file(binding.get("source"), f"{what} source")
                if path is None:
                    continue
                try:
                    inline = ET.parse(path).getroot()
                except ET.ParseError as exc:
                    self.refuse(f"{what}: '{binding.get('source')}' is not well-formed XML ({exc})")
                    continue
            if inline is None or inline.tag != _q("ssv", "ParameterSet"):
                self.refuse(f"{what} holds no ssv:ParameterSet (inline in ssd:ParameterValues or as source)")
                continue
            prefix = binding.get("prefix", "")
            for name, value in self._parameter_set(inline, what).items():
                if name.startswith(prefix):
                    values[name[len(prefix):]] = value
        return values

    def _parameter_set(self, parameter_set: ET.Element, what: str) -> dict[str, float]:
        values = {}
        for parameter in parameter_set.iterfind(f"{_q('ssv', 'Parameters')}/{_q('ssv', 'Parameter')}"):
            name = parameter.get("name", "")
            typed = [child for child in parameter if _name(child) != "ssd:Annotations"]
            kind = _name(typed[0]) if typed else "nothing"
            if kind not in ("ssv:Real", "ssv:Integer"):
                self.refuse(f"ssv:Parameter '{name}' in the {what} is {kind}: featherstar sets Real and Integer "
                            "parameter values only")
                continue
            if typed[0].get("unit"):
                self.refuse(f"ssv:Parameter '{name}' in the {what} has unit '{typed[0].get('unit')}': featherstar "
                            "does not convert parameter units (give the value in the FMU's unit, without unit)")
                continue
            number = self._float(typed[0], "value", f"ssv:Parameter '{name}' in the {what}", None)
            if number is not None:
                values[name] = number
        return values

    # --- connections -----------------------------------------------------------------------
    def _connection(self, connection: ET.Element, blocks: dict[str, Any], own: dict[str, Any],
                    connectors: dict[str, str]) -> str | list[str] | tuple[str] | None:
        start = (connection.get("startElement"), connection.get("startConnector"))
        end = (connection.get("endElement"), connection.get("endConnector"))
        label = f"ssd:Connection {'.'.join(filter(None, start)) or '?'} -> {'.'.join(filter(None, end)) or '?'}"
        if not start[1] or not end[1]:
            self.refuse(f"{label} needs a startConnector and an endConnector")
            return None
        linear = None
        for child in connection:
            if _name(child) == "ssc:LinearTransformation" and linear is None and start[0] and end[0]:
                linear = child
            elif _name(child) != "ssd:ConnectionGeometry":
                where = "" if start[0] and end[0] else " (transformations between components only)"
                self.refuse(f"{_name(child)} on the {label}: featherstar maps only ssc:LinearTransformation{where}")
                return None
        for element, _ in (start, end):
            if element is not None and element not in blocks:
                self.refuse(f"{label} names element '{element}', which is not a component of the system")
                return None
        units = (self.units.get(start), self.units.get(end))
        if all(units) and units[0] != units[1]:
            self.refuse(f"{label}: its connectors' units differ ('{units[0]}' -> '{units[1]}'); SSP tools convert "
                        "between them, featherstar converts no unit (give both connectors the same unit)")
            return None
        if linear is not None and f"{start[0]}.{start[1]} -> {end[0]}.{end[1]}" in self.transformed:
            return None
        if linear is not None:
            return self._transformed(linear, f"{start[0]}.{start[1]}", f"{end[0]}.{end[1]}", blocks, label)
        src = self._endpoint(start, own, connectors, "input", label)
        fed = end[1].partition(".")[0]   # a featherstar block the connector leads to, or the source itself
        if end[0] is None and src and (fed not in own or fed == start[0]) and connectors.get(end[1]) == "output":
            return (src,)  # a system output: recorded
        dst = self._endpoint(end, own, connectors, "output", label)
        return f"{src} -> {dst}" if src and dst else None

    def _transformed(self, linear: ET.Element, src: str, dst: str, blocks: dict[str, Any], label: str) -> list[str] | None:
        """src -> transform_<n>.u, transform_<n>.y -> dst through y = factor u + offset."""
        factor = self._float(linear, "factor", f"ssc:LinearTransformation on the {label}", 1.0)
        offset = self._float(linear, "offset", f"ssc:LinearTransformation on the {label}", 0.0)
        if factor is None or offset is None:
            return None
        if not (math.isfinite(factor) and math.isfinite(offset)):
            self.refuse(f"ssc:LinearTransformation on the {label}: factor = {factor!r}, offset = {offset!r} "
                        "must be finite")
            return None
        name = next(f"transform_{n}" for n in range(len(blocks) + 1) if f"transform_{n}" not in blocks)
        blocks[name] = {"kind": "gain", "gain": factor, "offset": offset, "unit_in": "", "unit_out": "",
                        "description": f"ssc:LinearTransformation of the {label}"}
        return [f"{src} -> {name}.u", f"{name}.y -> {dst}"]

    def _endpoint(self, endpoint: tuple[str | None, str], own: dict[str, Any], connectors: dict[str, str],
                  system_kind: str, label: str) -> str | None:
        element, connector = endpoint
        if element is not None:
            return f"{element}.{connector}"
        block = connector.partition(".")[0]
        if block in own:  # "block.port" of a featherstar block, through a system connector
            return connector
        if connectors.get(connector) != system_kind:
            self.refuse(f"{label}: the system has no {system_kind} connector '{connector}'")
        elif system_kind == "input":
            self.refuse(f"{label}: system input '{connector}' is driven by nothing featherstar knows; a run "
                        "needs a closed system (drive it from a component)")
        return None
