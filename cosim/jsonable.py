"""The one JSON sanitizer: plain, strict JSON from run summaries, study logs and reports.

Non-finite floats become the strings 'nan', 'inf', '-inf' (strict JSON has no such tokens),
numpy scalars plain numbers, tuples lists, mapping keys strings. `drop_arrays` leaves numpy arrays
out of mappings (traces belong in figures and CSV files, not in a summary)."""
from __future__ import annotations

import math
from typing import Any

import numpy as np


def json_safe(value: Any, *, drop_arrays: bool = False) -> Any:
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else str(value)
    if isinstance(value, dict):
        return {str(k): json_safe(v, drop_arrays=drop_arrays) for k, v in value.items()
                if not (drop_arrays and isinstance(v, np.ndarray))}
    if isinstance(value, (list, tuple)):
        return [json_safe(v, drop_arrays=drop_arrays) for v in value]
    return value
