"""The declared schema of a scene's [master] and [metrics] tables: each key's type, range, unit
and meaning, in one place, from which both the checks (`read_setting`, `setting_problems`) and
the parameter listing (`listing`) are generated.

A key is declared once, as a dataclass field whose metadata holds its `Setting`; its type is the
type of its default. A value from a TOML file must already have that type (an integer is a valid
float); a --set value is text and is parsed first (featherstar.cosim.scene.specs.parse_value).
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field, fields
from typing import Any, Iterator

from ..errors import SceneError

TYPE_NAMES = {bool: "bool", int: "int", float: "float", str: "str"}


@dataclass(frozen=True)
class Setting:
    """What one key may hold. Numbers: lo <= value <= hi (either bound optional), or exactly 0
    when `zero_means` says what 0 stands for; strings: one of `choices`, or a "block.port"
    signal name (or empty) when `signal`."""

    meaning: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    zero_means: str = ""
    choices: tuple[str, ...] = ()
    signal: bool = False

    def bounds_text(self) -> str:
        if self.lo is not None and self.hi is not None:
            text = f"in [{self.lo:g}, {self.hi:g}]"
        elif self.lo is not None:
            text = f">= {self.lo:g}"
        elif self.hi is not None:
            text = f"<= {self.hi:g}"
        else:
            text = ""
        if self.zero_means and self.lo is not None and self.lo > 0:
            text = f"0 ({self.zero_means}) or {text}"
        return text


def setting(default: Any, meaning: str, unit: str = "", **limits: Any) -> Any:
    """A dataclass field declaring one key: its default, meaning, unit and limits (`Setting`)."""
    return field(default=default, metadata={"setting": Setting(meaning, unit, **limits)})


def declared(cls: Any) -> Iterator[tuple[str, type, Any, Setting]]:
    """(name, type, default, Setting) of every declared key of a settings dataclass."""
    for f in fields(cls):
        yield f.name, type(f.default), f.default, f.metadata["setting"]


def close_match(word: str, candidates: Any) -> str:
    """"; did you mean ..." with the closest candidate, or nothing."""
    match = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    return f"; did you mean '{match[0]}'?" if match else ""


def unknown_key(section: str, key: str, known: Any) -> str:
    """The refusal of a key the section does not have, with the closest known one."""
    known = list(known)
    return f"{section} has no setting '{key}'{close_match(key, known)} (it has: {', '.join(known)})"


def read_setting(section: str, key: str, kind: type, raw: Any, value: Any, spec: Setting) -> Any:
    """`value` (raw, or raw parsed from --set text) as the key's type, or a SceneError naming
    section.key, the value given and what was expected. Ranges are `setting_problems`'."""
    expected = spec.bounds_text() or (f"one of {', '.join(spec.choices)}" if spec.choices else "")
    hint = f" ({spec.meaning}; expected {TYPE_NAMES[kind]}{' ' + expected if expected else ''})"
    bad = SceneError(f"{section}.{key} = {raw!r} is not a valid {TYPE_NAMES[kind]}{hint}")
    if kind is bool:
        if not isinstance(value, bool):
            raise bad
        return value
    if kind is str:   # text stays text: a --set value is a string before any parsing
        if not isinstance(raw, str):
            raise bad
        return raw.strip()
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise bad
    if kind is int:
        if not (math.isfinite(value) and float(value).is_integer()):
            raise bad
        return int(value)
    return float(value)


def value_problem(section: str, key: str, value: Any, spec: Setting) -> str | None:
    """Why a value of the right type is out of its declared range (None: it is in range)."""
    name = f"{section}.{key} = {value!r}"
    if isinstance(value, str):
        if spec.choices and value not in spec.choices:
            return f"{name} is not one of {', '.join(spec.choices)}{close_match(value, spec.choices)}"
        if spec.signal and value:
            block, dot, port = value.partition(".")
            if not (dot and block.strip() and port.strip()):
                return f"{name} must name a recorded signal as 'block.port' ({spec.meaning})"
        return None
    if isinstance(value, bool):
        return None
    if spec.zero_means and value == 0:
        return None
    ok = math.isfinite(value) and (spec.lo is None or value >= spec.lo) and (spec.hi is None or value <= spec.hi)
    if ok:
        return None
    what = "an integer" if isinstance(value, int) else "a finite number"
    unit = f" {spec.unit}" if spec.unit and spec.unit != "1" else ""
    return f"{name} must be {what} {spec.bounds_text()}{unit} ({spec.meaning})"


def setting_problems(obj: Any, section: str) -> list[str]:
    """Every declared key of `obj` whose value is out of range, one line each."""
    problems = []
    for name, _kind, _default, spec in declared(type(obj)):
        problem = value_problem(section, name, getattr(obj, name), spec)
        if problem:
            problems.append(problem)
    return problems


def listing(cls: Any, section: str) -> list[str]:
    """One line per key: name, type, default, range and unit, meaning (`featherstar` help text,
    docs)."""
    rows = []
    for name, kind, default, spec in declared(cls):
        allowed = spec.bounds_text() or ("|".join(spec.choices) if spec.choices else
                                         "block.port or empty" if spec.signal else "")
        unit = "" if spec.unit in ("", "1") else f" {spec.unit}"
        zero = f" (0 = {spec.zero_means})" if spec.zero_means and "(" not in allowed else ""
        rows.append(f"{section}.{name:<22} {TYPE_NAMES[kind]:<5} default {default!r:<10} "
                    f"{allowed}{unit}  {spec.meaning}{zero}".rstrip())
    return rows
