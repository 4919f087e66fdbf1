"""Typed access to a register-map document, with errors naming the file, the key and the
valid values (featherstar.hil.registers, featherstar.hil.timed_registers)."""
from __future__ import annotations

import math
from typing import Any, Sequence

from .errors import HILConfigError


class MapReader:
    """Typed access to one map file with errors naming the file, the key and the valid values."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, message: str) -> HILConfigError:
        return HILConfigError(f"register map {self.source}: {where}: {message}")

    def table(self, doc: dict[str, Any], name: str, required: bool) -> dict[str, Any] | None:
        if name not in doc:
            if required:
                raise self.fail(f"[{name}]", "missing section")
            return None
        if not isinstance(doc[name], dict):
            raise self.fail(f"[{name}]", "must be a table")
        return doc[name]

    def check_keys(self, section: str, table: dict[str, Any], valid: set[str]) -> None:
        for key in table:
            if key not in valid:
                raise self.fail(f"[{section}] {key}",
                                f"unknown key; valid keys: {', '.join(sorted(valid))}")

    def choice(self, section: str, table: dict[str, Any], key: str, valid: Sequence[Any],
               default: Any = None) -> Any:
        if key not in table:
            if default is None:
                raise self.fail(f"[{section}] {key}",
                                f"missing; valid values: {', '.join(map(str, valid))}")
            return default
        value = table[key]
        # Compare types too: TOML `true` == 1 and `1.0` == 1 in Python, neither is a valid base.
        if not any(value == v and type(value) is type(v) for v in valid):
            raise self.fail(f"[{section}] {key} = {value!r}",
                            f"not valid; valid values: {', '.join(map(str, valid))}")
        return value

    def integer(self, section: str, table: dict[str, Any], key: str, lo: int, hi: int,
                required: bool = False) -> int | None:
        if key not in table:
            if required:
                raise self.fail(f"[{section}] {key}", f"missing; an integer in {lo}..{hi}")
            return None
        value = table[key]
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise self.fail(f"[{section}] {key} = {value!r}", f"must be an integer in {lo}..{hi}")
        return value

    def number(self, section: str, table: dict[str, Any], key: str,
               default: float | None) -> float | None:
        if key not in table:
            return default
        value = table[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value):
            raise self.fail(f"[{section}] {key} = {value!r}", "must be a finite number")
        return float(value)


def map_address(r: MapReader, section: str, table: dict[str, Any], key: str, base: int,
             required: bool = True) -> int | None:
    printed = r.integer(section, table, key, base, 65535 + base, required)
    return None if printed is None else printed - base
