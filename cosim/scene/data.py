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

    [master]                               # see MasterSpec for every key and its default
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
import math
import tomllib
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

from ..errors import SceneError
from .blocks import block_kind
from .specs import BlockSpec, Connection, FrozenMap, PortRef, parse_value

COUPLINGS = ("strong", "jacobi", "gauss-seidel")
METHODS = ("bdf", "adams", "adams-fixedpoint")


@dataclass(frozen=True)
class MasterSpec:
    """How the master runs a scene.

    coupling           strong: ME FMUs (and memoryless Python blocks) integrated together as one
                       ODE by CVODE; jacobi / gauss-seidel: blocks stepped as co-simulation
                       units, inputs held (zero-order hold) over each macro step.
    method             CVODE method for strong coupling and for ME-only FMUs in weak coupling:
                       bdf (stiff) or adams (non-stiff).
    rtol, atol         tolerances of every error-controlled integrator (CVODE here; passed to
                       CS FMUs as their tolerance), and of the adaptive macro-step control.
    step_s             weak coupling: the macro (communication) step; the initial one if adaptive.
    max_step_s         strong coupling: largest solver step (0 = no limit).
    adaptive           weak coupling: control the macro step from an error estimate, rejecting
                       and rolling back steps whose estimate exceeds the tolerance.
    macro_rtol         adaptive macro step: tolerated zero-order-hold error, relative to each
                       coupled input's running magnitude (half its change over a step).
    min_step_s, max_macro_step_s   bounds of the adaptive macro step.
    t_end_s            run length; 0 = `periods` periods of the scene's stroke.
    periods            run length in stroke periods when t_end_s = 0.
    output_interval_s  recording grid (strong coupling; weak records every communication point).
    dedup              integrate identical blocks driven by identical signals once.
    loop_tol, loop_max_iter   algebraic-loop iteration (Newton with a finite-difference Jacobian).
    algebraic_loops    iterate | error: whether algebraic loops may be solved by iteration.
    backend            fmu: model blocks run as exported FMUs through fmpy; casadi: in-process
                       (no export; for development and for FMU-free checks).
    realtime           weak coupling: pace macro steps on the wall clock (hardware in the loop);
                       steps that start late are counted as deadline misses.
    check_steps        refuse a recording grid or fixed macro step too coarse for the stroke, and a
                       macro step too long for a feedback loop (featherstar.cosim.scene.guards); false only to study
                       the sampling or coupling error itself.
    passive_energy_factor  stop when a passive block (a feather) gains more than this multiple of
                       the work its ports put in (featherstar.cosim.scene.guards); 0 = no check.
    compiled_rhs       strong coupling: run the right-hand side as compiled C calls
                       (featherstar.cosim.coupling.compiled_rhs; needs gcc); false: the Python path.
    start_at_rest      strong coupling: start from the state in which every continuous state's
                       derivative is zero for the inputs at the start (a bench left alone:
                       featherstar.cosim.coupling.rest), not from the models' start values.
    """

    coupling: str = "strong"
    method: str = "bdf"
    rtol: float = 1e-6
    atol: float = 1e-8
    step_s: float = 1e-3
    max_step_s: float = 0.0
    adaptive: bool = False
    macro_rtol: float = 1e-3
    min_step_s: float = 1e-7
    max_macro_step_s: float = 0.05
    t_end_s: float = 0.0
    periods: float = 6.0
    output_interval_s: float = 1e-3
    dedup: bool = True
    loop_tol: float = 1e-10
    loop_max_iter: int = 50
    algebraic_loops: str = "iterate"
    backend: str = "fmu"
    realtime: bool = False
    check_steps: bool = True
    passive_energy_factor: float = 2.0
    compiled_rhs: bool = True
    start_at_rest: bool = False

    def check(self) -> list[str]:
        problems = []
        if self.coupling not in COUPLINGS:
            problems.append(f"master.coupling = '{self.coupling}' is not one of {', '.join(COUPLINGS)}")
        if self.method not in METHODS:
            problems.append(f"master.method = '{self.method}' is not one of {', '.join(METHODS)}")
        if self.algebraic_loops not in ("iterate", "error"):
            problems.append(f"master.algebraic_loops = '{self.algebraic_loops}' is not iterate or error")
        if self.backend not in ("fmu", "casadi"):
            problems.append(f"master.backend = '{self.backend}' is not fmu or casadi")
        for name in ("rtol", "atol", "step_s", "output_interval_s", "loop_tol", "min_step_s", "max_macro_step_s",
                     "macro_rtol"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                problems.append(f"master.{name} = {v!r} must be > 0")
        for name in ("t_end_s", "periods", "max_step_s", "passive_energy_factor"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                problems.append(f"master.{name} = {v!r} must be >= 0")
        if self.realtime and self.coupling == "strong":
            problems.append("master.realtime needs a weak coupling (jacobi or gauss-seidel): hardware "
                            "cannot be integrated inside one ODE")
        if self.start_at_rest and self.coupling != "strong":
            problems.append("master.start_at_rest needs master.coupling = strong: the state at rest is solved "
                            "on the coupled ODE")
        if self.t_end_s == 0 and self.periods == 0:
            problems.append("master: set t_end_s or periods")
        return problems


@dataclass(frozen=True)
class MetricsSpec:
    """Which signals the paper's metrics read. Empty = metric not computed.

    thrust          thrust signal (N) for mean thrust (Eq. 2) and thrust ratio TR (Eq. 3)
    angle           root angle (rad), drawn with the thrust in the figure
    speed           body speed (m/s) for the robot's mean speed
    position        body position (m); mean speed = displacement / window when given
    settle_periods  metrics use whole periods after this many periods of transient
    period_s        metric period; 0 = the period of the scene's stroke controller
    """

    thrust: str = ""
    angle: str = ""
    speed: str = ""
    position: str = ""
    settle_periods: float = 3.0
    period_s: float = 0.0

    def signals(self) -> list[str]:
        return [s for s in (self.thrust, self.angle, self.speed, self.position) if s]

    def check(self) -> list[str]:
        problems = []
        for name in ("settle_periods", "period_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                problems.append(f"metrics.{name} = {v!r} must be a finite number >= 0")
        return problems


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
        raise SceneError(
            f"no block named '{name}'; the scene has: {', '.join(b.name for b in self.blocks)}", self.name
        )

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
            try:
                new = block_kind(spec.kind, scene.name).override_batch(spec, items)
            except SceneError as exc:
                problems.extend(exc.problems)
                continue
            scene = dataclasses.replace(scene, blocks=tuple(new if b.name == name else b for b in scene.blocks))
        if problems:
            raise SceneError(problems, self.name)
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
    by_name = {f.name: f for f in fields(obj)}
    if key not in by_name:
        raise SceneError(f"{section} has no setting '{key}'; it has: {', '.join(by_name)}")
    current = getattr(obj, key)
    value = parse_value(raw)
    try:
        if isinstance(current, bool):
            if not isinstance(value, bool):
                raise ValueError
        elif isinstance(current, int):
            if isinstance(value, bool) or float(value) != int(float(value)):
                raise ValueError
            value = int(float(value))
        elif isinstance(current, float):
            if isinstance(value, bool):
                raise ValueError
            value = float(value)
        else:
            value = str(value)
    except (TypeError, ValueError):
        raise SceneError(f"{section}.{key} = {raw!r} is not a valid {type(current).__name__}") from None
    return dataclasses.replace(obj, **{key: value})


def _dataclass_from(cls: Any, table: Mapping[str, Any], section: str, problems: list[str]) -> Any:
    obj = cls()
    for key, value in table.items():
        try:
            obj = _override_dataclass(obj, section, key, value)
        except SceneError as exc:
            problems.extend(exc.problems)
    return obj


def scene_from_dict(data: Mapping[str, Any], *, name: str = "", source: str = "") -> Scene:
    """Build a Scene from parsed TOML (or an equivalent dict). Checks the file's shape; the
    wiring is checked by `featherstar.cosim.scene.graph.validate` (before anything is loaded)."""
    problems: list[str] = []
    known = {"name", "description", "connections", "aliases", "units", "master", "metrics", "blocks"}
    for key in data:
        if key not in known:
            problems.append(f"unknown top-level key '{key}' (known: {', '.join(sorted(known))})")
    name = str(data.get("name", name) or "scene")
    blocks = []
    raw_blocks = data.get("blocks", {})
    if not isinstance(raw_blocks, Mapping) or not raw_blocks:
        problems.append("a scene needs a [blocks.NAME] table per block")
        raw_blocks = {}
    for bname, table in raw_blocks.items():
        if not isinstance(table, Mapping):
            problems.append(f"block '{bname}' must be a table")
            continue
        if "." in bname or not bname:
            problems.append(f"block name '{bname}' must be non-empty and contain no '.'")
        kind = table.get("kind")
        if not isinstance(kind, str):
            problems.append(f"block '{bname}' has no kind (kind = \"fmu\", \"stroke\", \"recorder\", ...)")
            continue
        settings = {k: v for k, v in table.items() if k not in ("kind", "description")}
        if kind == "fmu" and isinstance(settings.get("fmu"), str) and source:
            fmu_path = Path(settings["fmu"]).expanduser()
            if not fmu_path.is_absolute():  # relative to the scene file
                settings["fmu"] = str(Path(source).resolve().parent / fmu_path)
        blocks.append(BlockSpec(bname, kind, FrozenMap(settings), FrozenMap(), str(table.get("description", ""))))
    connections = _connections(data.get("connections", []), "connections", problems)
    units = data.get("units", {})
    if not isinstance(units, Mapping) or set(units) - {"waive"}:
        problems.append("[units] takes one key: waive = [\"src.port -> dst.port\", ...]")
        units = {}
    unit_waivers = _connections(units.get("waive", []), "units.waive", problems)
    aliases = {}
    raw_aliases = data.get("aliases", {})
    if not isinstance(raw_aliases, Mapping):
        problems.append("[aliases] must map a name to a list of block names")
        raw_aliases = {}
    for alias, members in raw_aliases.items():
        if isinstance(members, str):
            members = [members]
        if not (isinstance(members, (list, tuple)) and all(isinstance(m, str) for m in members)):
            problems.append(f"alias '{alias}' must name a block or a list of blocks, not {members!r:.60}")
            continue
        aliases[alias] = tuple(members)
    master = _dataclass_from(MasterSpec, data.get("master", {}), "master", problems)
    metrics = _dataclass_from(MetricsSpec, data.get("metrics", {}), "metrics", problems)
    if problems:
        raise SceneError(problems, name)
    return Scene(
        name=name,
        description=str(data.get("description", "")),
        blocks=tuple(blocks),
        connections=tuple(connections),
        master=master,
        metrics=metrics,
        aliases=FrozenMap(aliases),
        source=source,
        unit_waivers=tuple(unit_waivers),
    )


def _connections(raw: Any, key: str, problems: list[str]) -> list[Connection]:
    """"src.port -> dst.port" strings (or [src, dst] pairs) as Connections; problems collected."""
    if not isinstance(raw, (list, tuple)):
        problems.append(f"{key} must be a list of \"src.port -> dst.port\" strings")
        return []
    label = "connection" if key == "connections" else f"{key}:"
    out = []
    for item in raw:
        try:
            if isinstance(item, str):
                src, arrow, dst = item.partition("->")
                if not arrow:
                    raise SceneError(f"{label} '{item}' must read 'block.output -> block.input'")
            elif isinstance(item, (list, tuple)) and len(item) == 2:
                src, dst = item
            else:
                raise SceneError(f"{label} {item!r} must read 'block.output -> block.input'")
            out.append(Connection(PortRef.parse(src, "output"), PortRef.parse(dst, "input")))
        except SceneError as exc:
            problems.extend(exc.problems)
    return out
