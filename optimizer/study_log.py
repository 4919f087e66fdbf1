"""What an optimizer study's log must hold on resume (`featherstar.optimizer.resume` rules).

Evaluations and estimates of indices 0..iterations-1, each at a point of the search space, and
in order: an evaluation per index, once, with no gap, and an estimate only after the evaluation
it follows. The simulated study (`featherstar.optimizer.bayes.optimize`) and the bench study
(`featherstar.optimizer.bench.study`) share these rules.
"""
from __future__ import annotations

import math
from typing import Mapping

from .errors import OptimizerError
from .log import ExperimentLog
from .resume import Entries
from .space import SearchSpace


def study_entries(space: SearchSpace, iterations: int, *, extra: Mapping[str, str] | None = None) -> list[Entries]:
    """What an optimizer log's records must be: evaluations and estimates of indices 0..iterations-1,
    each at a point of `space` (its variables, finite and inside the bounds). `extra`: more fields
    an evaluation carries (a bench study's)."""
    def planned(index) -> dict | None:
        return {} if 0 <= index < iterations else None

    def in_space(record: dict) -> str | None:
        params = record["params"]
        if sorted(params) != sorted(space.names):
            return f"{record['kind']} {record['index']} has variables {sorted(params)}, the space {sorted(space.names)}"
        for v in space.variables:
            x = params[v.name]
            if not (isinstance(x, (int, float)) and not isinstance(x, bool) and v.low <= x <= v.high):
                return f"{record['kind']} {record['index']}: {v.name} = {x!r} is outside [{v.low:g}, {v.high:g}]"
        if record["kind"] == "evaluation" and not (isinstance(record["thrust_ratio"], (int, float))
                                                   and math.isfinite(record["thrust_ratio"])):
            return f"evaluation {record['index']}: TR {record['thrust_ratio']!r} is not a finite number"
        return None

    plan = f"indices 0..{iterations - 1}: resume with --iterations of at least the logged count"
    common = {"index": "int", "params": "dict", "thrust_ratio": "number"}
    return [
        Entries("evaluation", {**common, "mean_thrust_N": "number", **(extra or {})}, key="index", planned=planned,
                plan=plan, check=in_space),
        Entries("estimate", {**common, "sd": "number"}, key="index", planned=planned, plan=plan, check=in_space),
    ]


def check_in_order(log: ExperimentLog) -> None:
    """Evaluations are logged in index order, none missing, and an estimate only after the
    evaluation it follows: anything else means a line was lost or moved."""
    evaluated = 0
    for record, line in zip(log.records, log.lines):
        if record["kind"] == "evaluation":
            if record["index"] != evaluated:
                raise OptimizerError(f"{log.path}: line {line} is evaluation {record['index']} where "
                                     f"evaluation {evaluated} comes next; a line was lost or moved (the log is damaged)")
            evaluated += 1
        elif record["kind"] == "estimate" and record["index"] >= evaluated:
            raise OptimizerError(f"{log.path}: line {line} is the estimate after evaluation "
                                 f"{record['index']}, which the log lacks before it; a line was lost (the log is damaged)")
