"""Every key a scene lets you set (`--set KEY=VALUE`), with its value, unit, range and meaning:
`scene_keys(plan)`, what `featherstar scenes SCENE` prints.

The keys come from where they are interpreted, so the list cannot drift from what `--set`
accepts: the master and metrics tables (their declared schema, featherstar.cosim.scene.settings),
each model block's
parameters (unit, range, description: fmu_src models) and build options, an FMU file's
parameters, a constant's outputs, and Python blocks that describe their own keys (a block object
with `settable_keys() -> list[SettableKey]`, as the stroke controller has).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

from .plan import Plan
from .settings import declared


@dataclass(frozen=True)
class SettableKey:
    """One settable key: `key` as --set takes it, its value in this scene, unit, range, meaning."""

    key: str
    value: Any
    unit: str = ""
    range: str = ""
    description: str = ""
    kind: str = "parameter"   # parameter | build option | setting


def _range(minimum: float, maximum: float, exclusive_minimum: bool = False) -> str:
    if not (math.isfinite(minimum) or math.isfinite(maximum)):
        return ""
    return f"{'(' if exclusive_minimum else '['}{minimum:g}, {maximum:g}]"


def _section(prefix: str, spec: Any) -> list[SettableKey]:
    out = []
    for name, _kind, _default, declared_as in declared(type(spec)):
        allowed = declared_as.bounds_text() or ("|".join(declared_as.choices) if declared_as.choices else "")
        unit = "" if declared_as.unit in ("", "1") else declared_as.unit
        meaning = declared_as.meaning + (f" (0 = {declared_as.zero_means})" if declared_as.zero_means else "")
        out.append(SettableKey(f"{prefix}.{name}", getattr(spec, name), unit, allowed, meaning, "setting"))
    return out


def scene_keys(plan: Plan) -> list[SettableKey]:
    """Every settable key of the planned scene, master and metrics first, then block by block."""
    scene = plan.scene
    out = _section("master", scene.master) + _section("metrics", scene.metrics)
    for name in scene.block_names:
        rb = plan.blocks[name]
        if rb.model is not None:
            for option, value in sorted(dict(rb.model.options).items()):
                out.append(SettableKey(f"{name}.{option}", value, "", "", "build option (changes the equations)",
                                   "build option"))
            for p in rb.model.parameters:
                unit = "" if p.unit in ("1", "-") else p.unit
                out.append(SettableKey(f"{name}.{p.name}", rb.parameters.get(p.name, p.default), unit,
                                   _range(p.minimum, p.maximum, p.exclusive_minimum), p.description))
        elif rb.fmu_info is not None:
            info = rb.fmu_info
            for pname in sorted(info.parameters):
                out.append(SettableKey(f"{name}.{pname}", rb.parameters.get(pname, "(the FMU's start value)"), "",
                                   "", info.parameter_types.get(pname, "")))
        elif rb.obj is not None and callable(getattr(rb.obj, "settable_keys", None)):
            out += [dataclasses.replace(s, key=f"{name}.{s.key}") for s in rb.obj.settable_keys()]
        elif rb.spec.kind == "constant":
            for port, entry in dict(rb.spec.settings.get("outputs", {})).items():
                value = rb.spec.overrides.get(port, entry.get("value") if isinstance(entry, Mapping) else entry)
                unit = entry.get("unit", "") if isinstance(entry, Mapping) else ""
                out.append(SettableKey(f"{name}.{port}", value, unit, "", "constant output"))
    return out


def format_keys(settings: list[SettableKey]) -> str:
    """A plain-text table, one key per line, grouped by block."""
    lines, group = [], None
    width = max((len(s.key) for s in settings), default=0)
    for s in settings:
        head = s.key.split(".")[0]
        if head != group:
            lines.append(f"[{head}]")
            group = head
        value = f"{s.value:g}" if isinstance(s.value, float) else str(s.value)
        unit = f" {s.unit}" if s.unit else ""
        extra = "  ".join(x for x in (s.range, s.description) if x)
        lines.append(f"  {s.key:<{width}}  {value + unit:<18}  {extra}".rstrip())
    return "\n".join(lines)
