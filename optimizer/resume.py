"""What a resumed log must hold: the one validator every log-backed command runs before it resumes.

`featherstar.optimizer.log` refuses what is not a record at all (bytes that are not UTF-8 JSON, a
record that does not match its digest, a second header). This module refuses records that are
well formed but do not belong to the run being resumed, by the rules each command declares with
`Entries`:

* every record's kind is one the command writes, with the fields it needs, of the right types;
* an entry named by a key (a sweep run's index, an evaluation's index, a validation's
  controller) appears at most once: a duplicated line is refused, not silently deduplicated;
* a keyed entry must be one the run plans (no index beyond the grid or the budget), and where the
  plan fixes some of its fields (a sweep run's geometry and controller) they must be the plan's:
  an entry moved to another index, or another setup's entry, is refused.

Each refusal is one OptimizerError line naming the file, the line and what is wrong.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Hashable, Mapping, Sequence

from .errors import OptimizerError
from .log import ExperimentLog

# Field types, by name: "number" also takes the strings the log spells non-finite floats with.
_NON_FINITE = {"nan", "inf", "-inf"}


_TYPES = {"str": str, "bool": bool, "dict": dict, "list": list}


def _is(kind: str, value: Any) -> bool:
    if kind == "number":
        return (isinstance(value, (int, float)) and not isinstance(value, bool)) or value in _NON_FINITE
    if kind == "int":
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, _TYPES[kind])


@dataclass(frozen=True)
class Entries:
    """The records of one kind a command writes.

    `fields`: name → type ("number", "int", "str", "bool", "dict", "list").
    `key`: the field naming an entry (at most once per log); None for events that may repeat.
    `planned`: for a key, the fields the plan fixes (compared with the record), or None when the
    plan has no such entry; `plan` says in words what the plan holds (for the message).
    `check`: a further per-record check returning a problem, or None.
    """

    kind: str
    fields: Mapping[str, str]
    key: str | None = None
    planned: Callable[[Hashable], Mapping[str, Any] | None] | None = None
    plan: str = ""
    check: Callable[[dict], str | None] | None = None


def check_log(log: ExperimentLog, entries: Sequence[Entries]) -> None:
    """Refuse (OptimizerError, one line) a resumed log whose records break `entries`' rules."""
    by_kind = {e.kind: e for e in entries}
    seen: dict[tuple[str, Hashable], int] = {}
    for record, line in zip(log.records, log.lines):
        where = f"{log.path}: line {line}"
        spec = by_kind.get(record["kind"])
        if spec is None:
            raise OptimizerError(f"{where}: a record of kind {record['kind']!r}, which this command never writes "
                                 f"(it writes {', '.join(sorted(by_kind))}); the log was edited or is another run's")
        for name, kind in spec.fields.items():
            if name not in record:
                raise OptimizerError(f"{where}: the {spec.kind} record has no {name!r}; the log was edited or damaged")
            if not _is(kind, record[name]):
                raise OptimizerError(f"{where}: {spec.kind} {name} = {record[name]!r} is not a {kind}; the log was "
                                     "edited or damaged")
        if spec.check is not None:
            problem = spec.check(record)
            if problem:
                raise OptimizerError(f"{where}: {problem}; the log was edited or damaged")
        if spec.key is None:
            continue
        key = record[spec.key]
        if (spec.kind, key) in seen:
            raise OptimizerError(f"{where} repeats the {spec.kind} {spec.key} {key!r} of line "
                                 f"{seen[spec.kind, key]}; a log holds each entry once (a duplicated line?)")
        seen[spec.kind, key] = line
        if spec.planned is None:
            continue
        fixed = spec.planned(key)
        if fixed is None:
            raise OptimizerError(f"{where}: {spec.kind} {spec.key} {key!r} is not one this run plans "
                                 f"({spec.plan or 'another setup'}); the log is another run's or was edited")
        for name, value in fixed.items():
            if not _same(record.get(name), value):
                raise OptimizerError(f"{where}: {spec.kind} {key!r} has {name} = {record.get(name)!r} where the plan "
                                     f"has {value!r}; the log was edited or is another setup's")


def _same(logged: Any, planned: Any) -> bool:
    if isinstance(planned, float) and _is("number", logged) and not isinstance(logged, str):
        return math.isclose(logged, planned, rel_tol=1e-12, abs_tol=1e-15)
    return logged == planned

