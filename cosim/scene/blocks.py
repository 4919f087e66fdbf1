"""Block kinds: what each `kind = "..."` of a scene means, its ports and its overrides.

Resolving a block (`resolve`) reads everything the wiring checks need — port names, units,
direct feedthrough, capabilities — without loading any FMU binary: catalog models are built
symbolically, external FMUs have only their modelDescription.xml read.

Kinds (the swimmer's `stroke` kind is added by featherstar.cosim.swimmer.kinds through
`register_kind`: the master knows no domain block)
  fmu       a model run as an FMU: `model` = catalog kind ("feather", "servo", "robot") or
            "pkg.module:function" returning a fmu_src Model, with `options` (build options) and
            `parameters`; or `fmu` = path to any FMI 2.0/3.0 FMU, with `parameters` (start values)
  recorder  records `signals` (list of "block.port"); no ports of its own
  constant  constant outputs: outputs = { NAME = { value = 0.0, unit = "m/s" } }
  gain      y = gain * u + offset (memoryless; for tests and unit glue); keys: gain, offset,
            unit_in, unit_out, can_iterate
  python    any object implementing featherstar.cosim.framework.block.Block: `factory` = "pkg.module:Class",
            constructed as Class(name=NAME, **parameters) (hardware blocks from featherstar.hil go here;
            their constructors must not touch hardware before start())
"""
from __future__ import annotations

import dataclasses
import functools
import importlib
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Hashable, Mapping

from ...fmu_src.errors import FeatherstarError
from ..errors import SceneError
from ..fmi.fmi_types import parameter_value
from ..framework.block import (
    Block,
    MemorylessBlock,
    Passivity,
    Port,
    RollbackBlock,
    can_iterate,
    passivity_by_convention,
)
from ..framework.feedthrough import model_feedthrough
from .specs import BlockSpec, FrozenMap, PortRef, parse_value


@dataclass
class ResolvedBlock:
    """A block's build artefact: ports and capabilities, plus what is needed to instantiate it."""

    spec: BlockSpec
    inputs: dict[str, Port]
    outputs: dict[str, Port]
    memoryless: bool = False
    iterable: bool = False
    continuous: bool = False  # may join the strong (one-ODE) group
    identity: Hashable | None = None  # equal identities + equal input sources => interchangeable
    period_s: float | None = None
    model: Any = None  # fmu_src Model for model-backed blocks
    parameters: dict[str, Any] = field(default_factory=dict)  # models: floats; FMU files: each variable's type
    fmu_path: Path | None = None
    fmu_info: Any = None
    obj: Any = None  # python block object (stroke, gain, python kinds)
    signals: tuple[PortRef, ...] = ()  # recorder
    records_only: bool = False  # a recorder: names signals to record, computes nothing
    can_rollback: bool = False  # its state can be saved and restored (the adaptive weak master rejects steps)
    gives_period: bool = False  # its period_s is the scene's period (run length, metric window)
    ramps_s: tuple[tuple[float, str], ...] = ()  # its fastest transitions (s, the setting naming each): step guards
    shared_parameters: Mapping[str, float] = field(default_factory=dict)  # given to model blocks leaving them unset
    passivity: Passivity | None = None  # a passive block's energy output and power ports (the energy guard)
    notes: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.spec.name


class BlockKind:
    name = ""

    def resolve(self, spec: BlockSpec) -> ResolvedBlock:
        raise NotImplementedError

    def override(self, spec: BlockSpec, key: str, raw: Any) -> BlockSpec:
        return dataclasses.replace(spec, overrides=spec.overrides.set(key, parse_value(raw)))

    def override_batch(self, spec: BlockSpec, items: Mapping[str, Any]) -> BlockSpec:
        """Apply one batch of overrides (one `with_overrides` call) to a block."""
        problems = []
        for key, raw in items.items():
            try:
                spec = self.override(spec, key, raw)
            except SceneError as exc:
                problems.extend(exc.problems)
        if problems:
            raise SceneError(problems)
        return spec


def where(spec: BlockSpec) -> str:
    return f"block '{spec.name}' ({spec.kind})"


# --- recorder -----------------------------------------------------------------------------------

class RecorderKind(BlockKind):
    name = "recorder"

    def resolve(self, spec: BlockSpec) -> ResolvedBlock:
        unknown = [k for k in spec.settings if k != "signals"]
        if unknown:
            raise SceneError(f"{where(spec)}: unknown key(s) {unknown}; a recorder has only 'signals'")
        signals = spec.overrides.get("signals", spec.settings.get("signals", ()))
        if isinstance(signals, str):
            signals = [s for s in signals.split(",") if s.strip()]
        refs = tuple(PortRef.parse(str(s), f"{where(spec)} signal") for s in signals)
        return ResolvedBlock(spec, {}, {}, memoryless=True, iterable=True, continuous=True, signals=refs,
                             records_only=True, can_rollback=True)


# --- gain ---------------------------------------------------------------------------------------

class Gain:
    """y = gain * u + offset."""

    def __init__(self, name: str, gain: float = 1.0, offset: float = 0.0, unit_in: str = "1",
                 unit_out: str = "1", can_iterate: bool = True) -> None:
        self.name = name
        self.gain, self.offset = float(gain), float(offset)
        self.can_iterate = bool(can_iterate)
        self.inputs = {"u": Port("u", unit_in)}
        self.outputs = {"y": Port("y", unit_out, depends_on=("u",))}
        self._u = 0.0

    def evaluate(self, t_s: float, inputs: Mapping[str, float]) -> dict[str, float]:
        return {"y": self.gain * inputs["u"] + self.offset}

    def start(self, t0_s: float) -> None:
        pass

    def set_inputs(self, values: Mapping[str, float]) -> None:
        self._u = values.get("u", self._u)

    def get_outputs(self) -> dict[str, float]:
        return {"y": self.gain * self._u + self.offset}

    def do_step(self, t_s: float, h_s: float) -> None:
        pass

    def close(self) -> None:
        pass


class GainKind(BlockKind):
    name = "gain"
    KEYS = ("gain", "offset", "unit_in", "unit_out", "can_iterate")

    def override(self, spec: BlockSpec, key: str, raw: Any) -> BlockSpec:
        if key not in self.KEYS:
            raise SceneError(f"{where(spec)} has no setting '{key}'; it has: {', '.join(self.KEYS)}")
        return super().override(spec, key, raw)

    def resolve(self, spec: BlockSpec) -> ResolvedBlock:
        values = {**spec.settings, **spec.overrides}
        unknown = [k for k in values if k not in self.KEYS]
        if unknown:
            raise SceneError(f"{where(spec)}: unknown key(s) {unknown}; known: {', '.join(self.KEYS)}")
        obj = Gain(spec.name, **values)
        return ResolvedBlock(spec, dict(obj.inputs), dict(obj.outputs), memoryless=True,
                             iterable=obj.can_iterate, continuous=True,
                             identity=("gain", tuple(sorted(values.items()))), obj=obj, can_rollback=True)


# --- constant -----------------------------------------------------------------------------------

class Constant:
    """Constant outputs (e.g. still water: flow speed 0 on the test bed)."""

    can_iterate = True
    static = True

    def __init__(self, name: str, values: Mapping[str, tuple[float, str]]) -> None:
        self.name = name
        self.inputs: dict[str, Port] = {}
        self.outputs = {k: Port(k, unit) for k, (v, unit) in values.items()}
        self.values = {k: float(v) for k, (v, unit) in values.items()}

    def evaluate(self, t_s: float, inputs: Mapping[str, float]) -> dict[str, float]:
        return dict(self.values)

    def start(self, t0_s: float) -> None:
        pass

    def set_inputs(self, values: Mapping[str, float]) -> None:
        pass

    def get_outputs(self) -> dict[str, float]:
        return dict(self.values)

    def set_output(self, name: str, value: float) -> None:
        """A new value from outside the scene (Simulator.write): a command, the flow speed."""
        self.values[name] = float(value)

    def fmu_stand_in(self) -> tuple[str, dict[str, Any], dict[str, float]]:
        """The FMU that stands in for this block in an SSP package (featherstar.cosim.ssp.export):
        (catalog model kind, build options, parameter values)."""
        units = {name: port.unit for name, port in self.outputs.items()}
        return "constant_source", {"outputs": units}, {f"{name}_value": v for name, v in self.values.items()}

    def do_step(self, t_s: float, h_s: float) -> None:
        pass

    def close(self) -> None:
        pass


class ConstantKind(BlockKind):
    """`outputs = { flow_speed_m_s = { value = 0.0, unit = "m/s" } }`; --set NAME.port=value."""

    name = "constant"

    def override(self, spec: BlockSpec, key: str, raw: Any) -> BlockSpec:
        if key not in dict(spec.settings.get("outputs", {})):
            raise SceneError(f"{where(spec)} has no output '{key}'")
        return super().override(spec, key, raw)

    def resolve(self, spec: BlockSpec) -> ResolvedBlock:
        unknown = [k for k in spec.settings if k != "outputs"]
        if unknown:
            raise SceneError(f"{where(spec)}: unknown key(s) {unknown}; a constant has only 'outputs'")
        values = {}
        for port, entry in dict(spec.settings.get("outputs", {})).items():
            if not isinstance(entry, Mapping) or "value" not in entry or "unit" not in entry:
                raise SceneError(f"{where(spec)}: output '{port}' must read {{ value = 0.0, unit = \"m/s\" }}")
            value = spec.overrides.get(port, entry["value"])
            if isinstance(value, (str, bool)):
                raise SceneError(f"{where(spec)}: {port} = {value!r} is not a number")
            values[port] = (float(value), str(entry["unit"]))
        obj = Constant(spec.name, values)
        return ResolvedBlock(spec, {}, dict(obj.outputs), memoryless=True, iterable=True, continuous=True,
                             identity=("constant", tuple(sorted(values.items()))), obj=obj, can_rollback=True)


# --- python -------------------------------------------------------------------------------------

#: A reference to Python code, exactly the strings `_import` accepts: "package.module:name", dotted
#: Python identifiers on both sides. Every kind imports through `_import`, from one string as the
#: scene wrote it; so a package (featherstar.cosim.ssp.code_refs refuses every string of this shape
#: in one) can make featherstar import nothing.
CODE_REFERENCE = re.compile(r"[^\W\d]\w*(?:\.[^\W\d]\w*)*:[^\W\d]\w*(?:\.[^\W\d]\w*)*")
_BLOCK_METHODS = ("start", "set_inputs", "get_outputs", "do_step", "close")


def _import(ref: str, where: str) -> Any:
    if not CODE_REFERENCE.fullmatch(ref):
        raise SceneError(f"{where}: '{ref}' must read 'package.module:name'")
    module, _, attr = ref.partition(":")
    try:
        obj = importlib.import_module(module)
    except ImportError as exc:
        raise SceneError(f"{where}: cannot import module '{module}' ({exc})") from None
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise SceneError(f"{where}: module '{module}' has no '{attr}'")
        obj = getattr(obj, part)
    return obj


def featherstar_block_class(ref: str) -> bool:
    """Whether `ref` names one of featherstar's own block classes (featherstar.hil.blocks:Servo,
    featherstar.optimizer.calibration.playback:RecordedRoot): a public class of a public module of
    the featherstar package (no name part starting with '_': never featherstar.__main__) with the
    Block methods. Deciding it imports that featherstar module, which runs featherstar's code only."""
    if not CODE_REFERENCE.fullmatch(ref):
        return False
    module, _, attr = ref.partition(":")
    parts = [*module.split("."), *attr.split(".")]
    if parts[0] != "featherstar" or "." not in module or any(p.startswith("_") for p in parts):
        return False
    try:
        obj = _import(ref, ref)
    except SceneError:
        return False
    return isinstance(obj, type) and all(callable(getattr(obj, m, None)) for m in _BLOCK_METHODS)


class PythonKind(BlockKind):
    name = "python"

    def override(self, spec: BlockSpec, key: str, raw: Any) -> BlockSpec:
        return dataclasses.replace(spec, overrides=spec.overrides.set(key, parse_value(raw)))

    def resolve(self, spec: BlockSpec) -> ResolvedBlock:
        factory_ref = spec.settings.get("factory")
        if not isinstance(factory_ref, str):
            raise SceneError(f"{where(spec)}: needs factory = \"package.module:Class\"")
        unknown = [k for k in spec.settings if k not in ("factory", "parameters")]
        if unknown:
            raise SceneError(f"{where(spec)}: unknown key(s) {unknown}; known: factory, parameters")
        factory = _import(factory_ref, where(spec))
        params = {**dict(spec.settings.get("parameters", {})), **spec.overrides}
        try:
            obj = factory(name=spec.name, **params)
        except FeatherstarError as exc:
            raise SceneError(f"{where(spec)}: {exc}") from None
        except TypeError as exc:
            raise SceneError(f"{where(spec)}: {factory_ref}(name=..., **parameters) failed: {exc}") from None
        if not isinstance(obj, Block):
            raise SceneError(f"{where(spec)}: {factory_ref} did not return a Block (needs name, inputs, "
                             "outputs, start, set_inputs, get_outputs, do_step, close)")
        memoryless = isinstance(obj, MemorylessBlock)
        return ResolvedBlock(spec, dict(obj.inputs), dict(obj.outputs), memoryless=memoryless,
                             iterable=can_iterate(obj), continuous=memoryless, identity=None,
                             period_s=getattr(obj, "period_s", None), obj=obj,
                             can_rollback=memoryless or isinstance(obj, RollbackBlock),
                             passivity=getattr(obj, "passivity", None))


# --- fmu ----------------------------------------------------------------------------------------

def _catalog_options(kind: str) -> tuple[str, ...]:
    """A catalog model's build options; none for a "pkg.module:function" model."""
    try:
        from ...fmu_src import catalog
    except ImportError:
        return ()
    try:
        return tuple(catalog.build_options(kind))
    except FeatherstarError:   # not a catalog kind
        return ()


@functools.lru_cache(maxsize=64)
def _model(model_ref: str, options: FrozenMap) -> Any:
    if ":" in model_ref:
        fn = _import(model_ref, f"model '{model_ref}'")
        return fn(**options)
    try:
        from ...fmu_src.catalog import build_model
    except ImportError as exc:  # pragma: no cover - the catalog ships with featherstar
        raise SceneError(f"model '{model_ref}': the model catalog is not available ({exc})") from None
    return build_model(model_ref, dict(options))


class FmuKind(BlockKind):
    name = "fmu"
    KEYS = ("model", "fmu", "options", "parameters", "interface")

    def override(self, spec: BlockSpec, key: str, raw: Any) -> BlockSpec:
        return dataclasses.replace(spec, overrides=spec.overrides.set(key, parse_value(raw)))

    def resolve(self, spec: BlockSpec) -> ResolvedBlock:
        unknown = [k for k in spec.settings if k not in self.KEYS]
        if unknown:
            raise SceneError(f"{where(spec)}: unknown key(s) {unknown}; known: {', '.join(self.KEYS)}")
        model_ref, fmu_ref = spec.settings.get("model"), spec.settings.get("fmu")
        if bool(model_ref) == bool(fmu_ref):
            raise SceneError(f"{where(spec)}: give exactly one of model = \"feather\" (a catalog model or "
                             "\"pkg.module:function\") or fmu = \"path/to/file.fmu\"")
        if model_ref:
            return self._resolve_model(spec, str(model_ref))
        return self._resolve_file(spec, str(fmu_ref))

    def _resolve_model(self, spec: BlockSpec, model_ref: str) -> ResolvedBlock:
        options = dict(spec.settings.get("options", {}))
        option_names = set(options) | set(_catalog_options(model_ref))
        param_overrides = {}
        for key, value in spec.overrides.items():
            if key in option_names:
                options[key] = value
            else:
                param_overrides[key] = value
        try:
            model = _model(model_ref, FrozenMap(options))
        except SceneError:
            raise
        except FeatherstarError as exc:
            raise SceneError(f"{where(spec)}: {exc}") from None
        except TypeError as exc:
            raise SceneError(f"{where(spec)}: model '{model_ref}' does not take options {options}: {exc}") from None
        names = {p.name for p in model.parameters}
        params, notes = {}, []
        for key, value in dict(spec.settings.get("parameters", {})).items():
            if key in names:
                params[key] = value
            else:  # e.g. width_ratio in the scene file while --set morphology=plain
                notes.append(f"scene parameter '{key}' ignored: model '{model.name}' "
                             f"({', '.join(f'{k}={v}' for k, v in options.items())}) has no such parameter")
        for key, value in param_overrides.items():
            if key not in names:
                raise SceneError(
                    f"{where(spec)}: model '{model_ref}' "
                    f"{'(' + ', '.join(f'{k}={v}' for k, v in options.items()) + ') ' if options else ''}"
                    f"has no parameter or build option '{key}'; parameters: {', '.join(sorted(names))}"
                    f"{'; build options: ' + ', '.join(sorted(option_names)) if option_names else ''}")
            if isinstance(value, (str, bool)):
                raise SceneError(f"{where(spec)}: parameter {key} = {value!r} is not a number")
            params[key] = value
        try:
            model.parameter_vector(params)  # range checks
        except FeatherstarError as exc:
            raise SceneError(f"{where(spec)}: {exc}") from None
        feed = model_feedthrough(model)
        inputs = {v.name: Port(v.name, v.unit, v.description) for v in model.inputs}
        outputs = {v.name: Port(v.name, v.unit, v.description, feed[v.name]) for v in model.outputs}
        identity = ("model", model_ref, FrozenMap(options), FrozenMap(params))
        return ResolvedBlock(spec, inputs, outputs, iterable=True, continuous=True, identity=identity,
                             model=model, parameters={k: float(v) for k, v in params.items()}, notes=notes,
                             can_rollback=True, passivity=passivity_by_convention(inputs, outputs))

    def _resolve_file(self, spec: BlockSpec, fmu_ref: str) -> ResolvedBlock:
        from ..fmi.archive import check_fmu_archive
        from ..fmi.fmu_info import read_fmu_info

        path = Path(fmu_ref).expanduser()
        if not path.exists():
            raise SceneError(f"{where(spec)}: FMU file '{fmu_ref}' does not exist")
        check_fmu_archive(path, where(spec))
        info = read_fmu_info(path, spec.name)
        overrides = dict(spec.overrides)
        interface = overrides.pop("interface", spec.settings.get("interface"))
        if interface is not None:
            info = _choose_interface(info, str(interface), where(spec))
        params = {**dict(spec.settings.get("parameters", {})), **overrides}
        if "options" in spec.settings:
            raise SceneError(f"{where(spec)}: build options apply to models, not to an FMU file")
        typed = {}
        for key, value in params.items():
            if key not in info.parameters:
                raise SceneError(f"{where(spec)}: FMU '{path.name}' has no tunable/fixed parameter '{key}'; "
                                 f"it has: {', '.join(sorted(info.parameters)) or 'none'}")
            try:
                typed[key] = parameter_value(info.parameter_types[key], value,
                                             f"{where(spec)}: parameter {key} ({info.parameter_types[key]})")
            except ValueError as exc:
                raise SceneError(str(exc)) from None
        return ResolvedBlock(spec, dict(info.inputs), dict(info.outputs), iterable=True,
                             continuous=info.has_me, identity=("fmu", str(path.resolve()), interface, FrozenMap(params)),
                             parameters=typed, fmu_path=path, fmu_info=info,
                             can_rollback=info.can_get_set_state,
                             passivity=passivity_by_convention(info.inputs, info.outputs))


def _choose_interface(info: Any, interface: str, where: str) -> Any:
    """The FMU seen through one interface only (`interface = "me"` or `"cs"`)."""
    md = info.model_description
    if interface == "me" and info.has_me:
        return dataclasses.replace(info, has_cs=False, can_get_set_state=bool(md.modelExchange.canGetAndSetFMUstate))
    if interface == "cs" and info.has_cs:
        return dataclasses.replace(info, has_me=False)
    if interface in ("me", "cs"):
        raise SceneError(f"{where}: interface = \"{interface}\" but the FMU has no "
                         f"{'Model Exchange' if interface == 'me' else 'Co-Simulation'} interface")
    raise SceneError(f"{where}: interface = {interface!r}; use \"me\" (Model Exchange) or \"cs\" (Co-Simulation)")


KINDS: dict[str, BlockKind] = {k.name: k for k in (RecorderKind(), ConstantKind(), GainKind(), PythonKind(), FmuKind())}


def register_kind(kind: BlockKind) -> None:
    """Add a block kind (a domain's blocks: featherstar.cosim.swimmer.kinds adds `stroke`)."""
    if kind.name in KINDS and type(KINDS[kind.name]) is not type(kind):
        raise ValueError(f"block kind '{kind.name}' is already registered as {type(KINDS[kind.name]).__name__}")
    KINDS[kind.name] = kind


def block_kind(kind: str, scene: str = "") -> BlockKind:
    if kind not in KINDS:
        raise SceneError(f"unknown block kind '{kind}'; known kinds: {', '.join(KINDS)}", scene)
    return KINDS[kind]


def resolve(spec: BlockSpec) -> ResolvedBlock:
    return block_kind(spec.kind).resolve(spec)
