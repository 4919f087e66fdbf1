"""Optional steps after the results are on disk: their failure is a warning, never a lost result.

Every command of the optimizer writes what it measured (logs, summary.json, CSVs, paper.json)
first and draws figures and comparisons after; `optional` runs such a step and turns its failure
into a PostProcessingWarning naming it, so a plotting bug or a bad comparison input never costs
the hours of simulation before it.
"""
from __future__ import annotations

import warnings
from typing import Any, Callable


class PostProcessingWarning(UserWarning):
    """An optional step (a figure, a comparison) failed after the results were written."""


def optional(step: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any | None:
    """fn(*args, **kwargs), or None with a PostProcessingWarning if it raises."""
    try:
        return fn(*args, **kwargs)
    except Exception as exc:  # noqa: BLE001 — whatever broke, the results before it stay
        reason = " ".join(str(exc).split()) or type(exc).__name__
        warnings.warn(f"{step} not done ({type(exc).__name__}: {reason}); the results before it are written",
                      PostProcessingWarning, stacklevel=2)
        return None
