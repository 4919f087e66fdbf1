"""Scenes as data: blocks, connections, master settings and metrics, loaded from TOML.

A scene is frozen: loading, overriding (`Scene.with_overrides`) and validating never mutate it;
everything that changes during a run lives in the master's per-run context. A scene file reads:

    name = "testbed"                       # optional, defaults to the file stem
    description = "one line for `featherstar scenes`"
    connections = [                        # output -> input, each input driven exactly once
        "controller.angle_rad -> servo.setpoint_rad",
        "feather.root_torque_Nm -> servo.load_torque_Nm",
    ]

    [aliases]                              # optional: one --set name for several blocks
    feather = ["feather_left", "feather_right"]

    [units]                                # optional: connections whose two declared units
    waive = ["vendor.y -> servo.setpoint_rad"]   # differ but whose values agree (checked by hand)

    [master]                               # see MasterSpec (cosim.scene.sections) for every key
    coupling = "strong"                    # strong | jacobi | gauss-seidel
    step_s = 1e-3

    [metrics]                              # see MetricsSpec
    thrust = "feather.thrust_N"

    [blocks.controller]                    # one table per block; `kind` picks the block type
    kind = "stroke"                        # stroke | fmu | recorder | gain | python
    t_up_s = 0.25

    [blocks.feather]
    kind = "fmu"
    model = "feather"                      # a catalog model, "pkg.module:function", or
    options = { morphology = "chordwise" } # fmu = "path/to/any.fmu" (FMI 2.0 or 3.0)
    parameters = { width_ratio = 7.5 }

Overrides are "block.key=value" strings (the CLI's --set): `master.*` and `metrics.*` set those
sections; for blocks, what a key means is up to the block kind (featherstar.cosim.scene.blocks).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from ..errors import SceneError
from .block_tables import block_table_problems
from .blocks import block_kind
from .sections import COUPLINGS, METHODS, MasterSpec, MetricsSpec
from .settings import close_match, declared, read_setting, unknown_key
from .specs import BlockSpec, Connection, FrozenMap, PortRef, parse_value

__all__ = ["COUPLINGS", "METHODS", "MasterSpec", "MetricsSpec", "Scene", "scene_from_dict"]

@dataclass(frozen=True)
class Scene:
    name: str
    description: str
    blocks: tuple[BlockSpec, ...]
    connections: tuple[Connection, ...]
    master: MasterSpec = MasterSpec()
    metrics: MetricsSpec = MetricsSpec()
    aliases: FrozenMap = field(default_factory=FrozenMap)
    source: str = ""
    unit_waivers: tuple[Connection, ...] = ()   # [units] waive: connections not unit-checked

    def block(self, name: str) -> BlockSpec:
        for b in self.blocks:
            if b.name == name:
                return b
        names = [b.name for b in self.blocks]
        raise SceneError(f"no block named '{name}'{close_match(name, names)} (the scene has: {', '.join(names)})",
                         self.name)

    @property
    def block_names(self) -> list[str]:
        return [b.name for b in self.blocks]

    def with_overrides(self, overrides: Mapping[str, Any] | None) -> "Scene":
        """A new scene with "block.key" -> value overrides applied (values may be strings)."""
        if not overrides:
            return self
        scene = self
        problems: list[str] = []
        batches: dict[str, dict[str, Any]] = {}
        for dotted, raw in overrides.items():
            target, dot, key = str(dotted).partition(".")
            if not dot or not key:
                problems.append(f"override '{dotted}' must read BLOCK.PARAM=VALUE")
                continue
            try:
                if target == "master":
                    scene = dataclasses.replace(scene, master=_override_dataclass(scene.master, "master", key, raw))
                elif target == "metrics":
                    scene = dataclasses.replace(scene, metrics=_override_dataclass(scene.metrics, "metrics", key, raw))
                else:
                    for name in list(scene.aliases.get(target, ())) or [target]:
                        scene.block(name)  # unknown block -> SceneError listing the blocks
                        batches.setdefault(name, {})[key] = raw
            except SceneError as exc:
                problems.extend(exc.problems)
        for name, items in batches.items():
            spec = scene.block(name)
            shape = block_table_problems(name, spec.kind, {k: parse_value(v) for k, v in items.items()})
            if shape:
                problems.extend(shape)
                continue
            try:
                new = block_kind(spec.kind, scene.name).override_batch(spec, items)
            except SceneError as exc:
                problems.extend(exc.problems)
                continue
            except (TypeError, ValueError, ArithmeticError) as exc:   # a kind meeting a value it cannot read
                problems.append(f"override {', '.join(f'{name}.{k}' for k in items)}: {exc}")
                continue
            scene = dataclasses.replace(scene, blocks=tuple(new if b.name == name else b for b in scene.blocks))
        if problems:   # ranges and wiring are the plan's checks: report the ranges here too
            raise SceneError(problems + scene.master.check() + scene.metrics.check(), self.name)
        return scene

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "description": self.description,
            "connections": [str(c) for c in self.connections],
            "aliases": self.aliases.to_plain(),
            # only when given, so that the fingerprints of scenes without waivers do not move
            **({"units": {"waive": [str(c) for c in self.unit_waivers]}} if self.unit_waivers else {}),
            "master": dataclasses.asdict(self.master),
            "metrics": dataclasses.asdict(self.metrics),
            "blocks": {
                b.name: {"kind": b.kind, **b.settings.to_plain(), **({"overrides": b.overrides.to_plain()} if b.overrides else {})}
                for b in self.blocks
            },
        }

    def fingerprint(self) -> str:
        text = json.dumps(self.to_dict(), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _override_dataclass(obj: Any, section: str, key: str, raw: Any) -> Any:
    """obj with one declared key set from `raw` (a TOML value, or --set text), type-checked
    against the section's schema (featherstar.cosim.scene.settings); ranges are `check()`'s."""
    by_name = {name: (kind, spec) for name, kind, _default, spec in declared(type(obj))}
    if key not in by_name:
        raise SceneError(unknown_key(section, key, by_name))
    kind, spec = by_name[key]
    value = read_setting(section, key, kind, raw, parse_value(raw), spec)
    return dataclasses.replace(obj, **{key: value})


def _dataclass_from(cls: Any, table: Any, section: str, problems: list[str]) -> Any:
    obj = cls()
    if not isinstance(table, Mapping):
        problems.append(f"[{section}] must be a table of settings, not {table!r}")
        return obj
    for key, value in table.items():
        try:
            obj = _override_dataclass(obj, section, str(key), value)
        except SceneError as exc:
            problems.extend(exc.problems)
    return obj


def _text(data: Mapping[str, Any], key: str, default: str, problems: list[str]) -> str:
    value = data.get(key, default)
    if not isinstance(value, str):
        problems.append(f"{key} = {value!r} must be a text")
        return default
    return value


def _blocks(raw_blocks: Any, source: str, problems: list[str]) -> list[BlockSpec]:
    if not isinstance(raw_blocks, Mapping) or not raw_blocks:
        problems.append("a scene needs a [blocks.NAME] table per block"
                        + (f", not blocks = {raw_blocks!r}" if raw_blocks else ""))
        return []
    blocks = []
    for bname, table in raw_blocks.items():
        if not isinstance(table, Mapping):
            problems.append(f"block '{bname}' must be a table ([blocks.{bname}] with kind = ...), "
                            f"not {table!r}")
            continue
        if not isinstance(bname, str) or "." in bname or not bname.strip():
            problems.append(f"block name {bname!r} must be a non-empty text without '.'")
            continue
        kind = table.get("kind")
        if not isinstance(kind, str):
            problems.append(f"block '{bname}' has no kind (kind = \"fmu\", \"stroke\", \"recorder\", ...)")
            continue
        description = table.get("description", "")
        if not isinstance(description, str):
            problems.append(f"{bname}.description = {description!r} must be a text")
        settings = {str(k): v for k, v in table.items() if k not in ("kind", "description")}
        shape = block_table_problems(bname, kind, settings)   # an unknown kind: the plan names it
        if shape:
            problems.extend(shape)
            continue
        if kind == "fmu" and isinstance(settings.get("fmu"), str) and source:
            fmu_path = Path(settings["fmu"]).expanduser()
            if not fmu_path.is_absolute():  # relative to the scene file
                settings["fmu"] = str(Path(source).resolve().parent / fmu_path)
        blocks.append(BlockSpec(bname, kind, FrozenMap(settings), FrozenMap(), str(description)))
    return blocks


def _connections(raw_conn: Any, problems: list[str], key: str = "connections") -> list[Connection]:
    if not isinstance(raw_conn, (list, tuple)):
        problems.append(f"{key} = {raw_conn!r} must be an array of \"src.port -> dst.port\" texts")
        return []
    connections = []
    for item in raw_conn:
        try:
            if isinstance(item, str):
                src, arrow, dst = item.partition("->")
                if not arrow:
                    raise SceneError(f"connection '{item}' must read 'block.output -> block.input'")
            elif (isinstance(item, (list, tuple)) and len(item) == 2
                  and all(isinstance(x, str) for x in item)):
                src, dst = item
            else:
                raise SceneError(f"connection {item!r} must read 'block.output -> block.input'")
            connections.append(Connection(PortRef.parse(src, "output"), PortRef.parse(dst, "input")))
        except SceneError as exc:
            problems.extend(exc.problems)
    return connections


def _aliases(raw: Any, problems: list[str]) -> dict[str, tuple[str, ...]]:
    if not isinstance(raw, Mapping):
        problems.append(f"aliases = {raw!r} must be a table (alias = [\"block\", ...])")
        return {}
    aliases = {}
    for alias, members in raw.items():
        if isinstance(members, str):
            members = [members]
        if not isinstance(members, (list, tuple)) or not all(isinstance(m, str) for m in members):
            problems.append(f"aliases.{alias} = {members!r} must be a block name or an array of them")
            continue
        aliases[str(alias)] = tuple(members)
    return aliases


def scene_from_dict(data: Mapping[str, Any], *, name: str = "", source: str = "") -> Scene:
    """Build a Scene from parsed TOML (or an equivalent dict: an SSP package's scene data).
    Checks every value's type and shape against the declared schema (featherstar.cosim.scene.settings,
    featherstar.cosim.scene.block_tables) and raises one SceneError listing every problem. Ranges
    (`MasterSpec.check`, `MetricsSpec.check`) are checked by the plan with the wiring, so that one
    SceneError lists them all (featherstar.cosim.scene.graph.plan, before anything is loaded)."""
    label = name or "scene"
    if not isinstance(data, Mapping):
        raise SceneError(f"a scene must be a table of settings, not {type(data).__name__}", label)
    problems: list[str] = []
    known = ("name", "description", "connections", "aliases", "units", "master", "metrics", "blocks")
    for key in data:
        if key not in known:
            problems.append(f"unknown top-level key '{key}'{close_match(str(key), known)} "
                            f"(known: {', '.join(sorted(known))})")
    name = _text(data, "name", name, problems) or "scene"
    description = _text(data, "description", "", problems)
    blocks = _blocks(data.get("blocks", {}), source, problems)
    connections = _connections(data.get("connections", []), problems)
    aliases = _aliases(data.get("aliases", {}), problems)
    units = data.get("units", {})
    if not isinstance(units, Mapping) or set(units) - {"waive"}:
        problems.append("[units] takes one key: waive = [\"src.port -> dst.port\", ...]")
        units = {}
    unit_waivers = _connections(units.get("waive", []), problems, "units.waive")
    master = _dataclass_from(MasterSpec, data.get("master", {}), "master", problems)
    metrics = _dataclass_from(MetricsSpec, data.get("metrics", {}), "metrics", problems)
    if problems:   # ranges and wiring are the plan's checks: report the ranges here too
        raise SceneError(problems + master.check() + metrics.check(), name)
    return Scene(
        name=name,
        description=description,
        blocks=tuple(blocks),
        connections=tuple(connections),
        master=master,
        metrics=metrics,
        aliases=FrozenMap(aliases),
        source=source,
        unit_waivers=tuple(unit_waivers),
    )
