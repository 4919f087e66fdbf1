"""Every key a scene lets you set (`--set KEY=VALUE`), with its value, unit, range and meaning:
`scene_settings(plan)`, what `featherstar scenes SCENE` prints.

The keys come from where they are interpreted, so the list cannot drift from what `--set`
accepts: the master and metrics tables (their fields and docstrings), each model block's
parameters (unit, range, description: fmu_src models) and build options, an FMU file's
parameters, a constant's outputs, and Python blocks that describe their own keys (a block object
with `settings() -> list[Setting]`, as the stroke controller has).
"""
from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from typing import Any, Mapping

from .plan import Plan


@dataclass(frozen=True)
class Setting:
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


def _field_docs(cls: Any) -> dict[str, str]:
    """Each field's text in a dataclass docstring written as `name   meaning` lines (MasterSpec)."""
    docs: dict[str, str] = {}
    current = None
    for line in (cls.__doc__ or "").splitlines():
        match = re.match(r"\s{4}(\w+(?:, \w+)*)\s{2,}(.*)", line)
        if match:
            current = [n.strip() for n in match.group(1).split(",")]
            for name in current:
                docs[name] = match.group(2).strip()
        elif current and line.startswith(" " * 8) and line.strip():
            for name in current:
                docs[name] += " " + line.strip()
        else:
            current = None
    return docs


def _unit_from_name(name: str) -> str:
    for suffix, unit in (("_deg", "deg"), ("_rad_s", "rad/s"), ("_rad", "rad"), ("_s", "s"), ("_N", "N"),
                         ("_m_s", "m/s"), ("_m", "m")):
        if name.endswith(suffix):
            return unit
    return ""


def _section(prefix: str, spec: Any) -> list[Setting]:
    docs = _field_docs(type(spec))
    return [Setting(f"{prefix}.{f.name}", getattr(spec, f.name), _unit_from_name(f.name), "",
                    docs.get(f.name, ""), "setting") for f in dataclasses.fields(spec)]


def scene_settings(plan: Plan) -> list[Setting]:
    """Every settable key of the planned scene, master and metrics first, then block by block."""
    scene = plan.scene
    out = _section("master", scene.master) + _section("metrics", scene.metrics)
    for name in scene.block_names:
        rb = plan.blocks[name]
        if rb.model is not None:
            for option, value in sorted(dict(rb.model.options).items()):
                out.append(Setting(f"{name}.{option}", value, "", "", "build option (changes the equations)",
                                   "build option"))
            for p in rb.model.parameters:
                unit = "" if p.unit in ("1", "-") else p.unit
                out.append(Setting(f"{name}.{p.name}", rb.parameters.get(p.name, p.default), unit,
                                   _range(p.minimum, p.maximum, p.exclusive_minimum), p.description))
        elif rb.fmu_info is not None:
            info = rb.fmu_info
            for pname in sorted(info.parameters):
                out.append(Setting(f"{name}.{pname}", rb.parameters.get(pname, "(the FMU's start value)"), "",
                                   "", info.parameter_types.get(pname, "")))
        elif rb.obj is not None and callable(getattr(rb.obj, "settings", None)):
            out += [dataclasses.replace(s, key=f"{name}.{s.key}") for s in rb.obj.settings()]
        elif rb.spec.kind == "constant":
            for port, entry in dict(rb.spec.settings.get("outputs", {})).items():
                value = rb.spec.overrides.get(port, entry.get("value") if isinstance(entry, Mapping) else entry)
                unit = entry.get("unit", "") if isinstance(entry, Mapping) else ""
                out.append(Setting(f"{name}.{port}", value, unit, "", "constant output"))
    return out


def format_settings(settings: list[Setting]) -> str:
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
