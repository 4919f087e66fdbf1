"""`featherstar paper --resume`: every finished experiment of the report, logged as it completes.

DIR/tasks.jsonl is an `featherstar.optimizer.log.ExperimentLog` whose header is the resolution
(less the worker count, which changes nothing measured) and whose records are one `task` per
finished experiment: its label and its result, numpy arrays spelled as {"ndarray": [...],
"dtype": ...}. A resumed report runs only the tasks the log lacks; the log is validated like
every other (`featherstar.optimizer.resume`): each planned label at most once, no other label.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Collection

import numpy as np

from ..log import ExperimentLog
from ..resume import Entries, check_log

TASK_LOG = "tasks.jsonl"
_NON_FINITE = {"nan": float("nan"), "inf": float("inf"), "-inf": float("-inf")}


def encode(value: Any) -> Any:
    """A task result as JSON-ready data (arrays tagged, to come back as arrays)."""
    if isinstance(value, np.ndarray):
        return {"ndarray": value.tolist(), "dtype": str(value.dtype)}
    if isinstance(value, dict):
        return {k: encode(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [encode(v) for v in value]
    return value


def decode(value: Any) -> Any:
    """`encode`'s inverse; the log's 'nan'/'inf' strings become floats again."""
    if isinstance(value, dict):
        if set(value) == {"ndarray", "dtype"}:
            return np.asarray(decode(value["ndarray"]), dtype=value["dtype"])
        return {k: decode(v) for k, v in value.items()}
    if isinstance(value, list):
        return [decode(v) for v in value]
    if isinstance(value, str) and value in _NON_FINITE:
        return _NON_FINITE[value]
    return value


class TaskLog:
    """The report's task log in `out_dir`; `done` holds the results read back on resume."""

    def __init__(self, out_dir: Path, resolution: dict, labels: Collection[str], *, resume: bool) -> None:
        header = {"paper": {k: v for k, v in resolution.items() if k != "workers"}}
        self._log = ExperimentLog.open(out_dir / TASK_LOG, header, resume=resume)
        planned = set(labels)
        check_log(self._log, [Entries("task", {"label": "str", "result": "dict"}, key="label",
                                      planned=lambda label: {} if label in planned else None,
                                      plan="the experiments of this resolution")])
        self.done: dict[str, dict] = {r["label"]: decode(r["result"]) for r in self._log.records}

    def append(self, label: str, result: dict) -> None:
        self._log.append({"kind": "task", "label": label, "result": encode(result)})
