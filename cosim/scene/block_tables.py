"""The shape of a block's table, checked where scene data enters (a TOML file, an SSP package's
scene data, a --set): which keys are tables, texts, signal lists or plain values. What a key
means stays each block kind's business (featherstar.cosim.scene.blocks); this only makes sure a
kind never meets a table where it reads a number, or a number where it reads a table.

The structural keys have one shape in every kind that has them:
  options, parameters, outputs     tables (`outputs` of tables with a number `value` and a text `unit`)
  model, fmu, factory, interface   text
  signals                          an array of "block.port" texts, or one comma-separated text
Every other key holds a plain value: a number, a boolean or a text. A catalog model's parameters
are numbers, its build options plain values; an FMU file's parameters are typed by its
modelDescription.xml and a Python block's by its factory.
"""
from __future__ import annotations

import math
from typing import Any, Mapping

TABLE_KEYS = ("options", "parameters", "outputs")
TEXT_KEYS = ("model", "fmu", "factory", "interface")
SCALARS = (bool, int, float, str)


def _plain(value: Any) -> bool:
    return isinstance(value, SCALARS)


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def block_table_problems(block: str, kind: str, values: Mapping[str, Any]) -> list[str]:
    """Every key of a block's settings (or of its overrides) in the wrong shape."""
    where = block
    problems = []
    for key, value in values.items():
        name = f"{where}.{key} = {value!r}"
        if key in TABLE_KEYS:
            if not isinstance(value, Mapping):
                problems.append(f"{name} must be a table ({key} = {{ name = value, ... }})")
                continue
            problems += _table_problems(f"{where}.{key}", key, kind, values, value)
        elif key in TEXT_KEYS:
            if not isinstance(value, str) or not value.strip():
                problems.append(f"{name} must be a non-empty text")
        elif key == "signals":
            items = [value] if isinstance(value, str) else value
            if not isinstance(items, (list, tuple)) or not all(isinstance(s, str) for s in items):
                problems.append(f"{name} must be an array of \"block.port\" texts")
        elif not _plain(value):
            problems.append(f"{name} must be a number, a boolean or a text, not a "
                            f"{'table' if isinstance(value, Mapping) else 'array'}")
        elif isinstance(value, float) and not math.isfinite(value):
            problems.append(f"{name} must be a finite number")
    return problems


def _table_problems(prefix: str, key: str, kind: str, values: Mapping[str, Any],
                    table: Mapping[str, Any]) -> list[str]:
    problems = []
    catalog_model = kind == "fmu" and "model" in values
    for item, value in table.items():
        name = f"{prefix}.{item} = {value!r}"
        if key == "outputs":
            if not (isinstance(value, Mapping) and _number(value.get("value"))
                    and isinstance(value.get("unit"), str)):
                problems.append(f"{name} must read {{ value = 0.0, unit = \"m/s\" }}")
        elif key == "parameters" and catalog_model:
            if not _number(value):
                problems.append(f"{name} must be a finite number (a model parameter)")
        elif key == "options" and not _plain(value):
            problems.append(f"{name} must be a number, a boolean or a text (a build option)")
    return problems
