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

from typing import Any, Mapping

from ..errors import SceneError
from ..framework.block import Port
from .block_kind import BlockKind, ResolvedBlock, where
from .fmu_blocks import FmuKind
from .python_blocks import PythonKind
from .specs import BlockSpec, PortRef


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
