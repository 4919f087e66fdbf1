"""A TOML writer for the generated-file tests (tomllib only reads): scenes and register maps
mutated by hypothesis are written back as files. Every key is quoted and every table is a
dotted header, so any data tomllib can return is written as data that reads back the same."""
from __future__ import annotations

import datetime
import json
import math
from typing import Any


def _string(text: str) -> str:
    # a TOML basic string: JSON's escapes, astral characters and DEL written as themselves / \u
    return json.dumps(text, ensure_ascii=False).replace("\x7f", "\\u007f")


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, (datetime.date, datetime.time)):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{_string(k)} = {_value(x)}" for k, x in v.items()) + "}"


def _table(lines: list[str], path: list[str], table: dict[str, Any]) -> None:
    lines.append("[" + ".".join(_string(p) for p in path) + "]")
    lines += [f"{_string(k)} = {_value(v)}" for k, v in table.items() if not isinstance(v, dict)]
    for k, v in table.items():
        if isinstance(v, dict):
            _table(lines, [*path, k], v)


def to_toml(data: dict[str, Any]) -> str:
    """`data` (str keys; TOML's value types) as a TOML document."""
    lines = [f"{_string(k)} = {_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for k, v in data.items():
        if isinstance(v, dict):
            _table(lines, [k], v)
    return "\n".join(lines) + "\n"
