"""Recorded load-cell runs for calibration: `featherstar run --hardware --out DIR` or any CSV.

A run is a CSV with a time, a root-angle and a thrust column (a DIR holding results.csv counts,
and its summary.json gives the stroke period). Columns are found by name (`time`, `time_s`,
`t`; `servo.angle_rad`, `root_angle_rad`, `angle_rad`, ...; `loadcell_hw.thrust_N`,
`thrust_N`, ...) or given explicitly; units come from a `name [unit]` header or a `_unit`
suffix: s | ms, rad | deg, N | mN. The runs of one calibration must agree in units and repeat
one stroke (`STROKE_TOLERANCE_FRACTION`): anything else is refused with one line naming the file.
"""
from __future__ import annotations

import csv
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import OptimizerError

# Column names looked for, best first, each bare or with a unit suffix (time_s, angle_deg, thrust_mN).
TIME_NAMES = ("time", "t")
ANGLE_NAMES = ("servo.angle", "root_angle", "angle", "controller.angle")
THRUST_NAMES = ("loadcell_hw.thrust", "feather.thrust", "thrust")
UNITS = {"time": {"s": 1.0, "ms": 1e-3}, "angle": {"rad": 1.0, "deg": math.pi / 180.0},
         "thrust": {"N": 1.0, "mN": 1e-3}}
# Repeats of one stroke differ by the real-time loop's timing jitter (10 ms at 5 rad/s is 3°):
# runs further apart than this share of the stroke's range (and at least 3°) are another stroke.
STROKE_TOLERANCE_FRACTION = 0.1
STROKE_TOLERANCE_MIN_RAD = math.radians(3.0)
_HEADER = re.compile(r"^\s*(?P<name>[^\[]+?)\s*(\[(?P<unit>[^\]]*)\])?\s*$")


@dataclass(frozen=True)
class Recording:
    """One run in SI units: time (s, from 0), root angle (rad), thrust (N); period if known;
    `complete` from the run's summary.json (False: the run stopped early or failed a check, and
    `incomplete_reason` says why; None: no summary)."""

    source: str
    time_s: np.ndarray
    angle_rad: np.ndarray
    thrust_N: np.ndarray
    units: tuple[str, str, str]
    period_s: float | None
    complete: bool | None = None
    incomplete_reason: str = ""


def _unit(name: str, unit: str | None, quantity: str, source: str) -> str:
    if not unit:
        suffix = name.rsplit("_", 1)[-1] if "_" in name else ""
        unit = suffix if suffix in UNITS[quantity] else {"time": "s", "angle": "rad", "thrust": "N"}[quantity]
    if unit not in UNITS[quantity]:
        raise OptimizerError(f"{source}: {quantity} column '{name}' is in '{unit}'; known units: "
                             f"{', '.join(UNITS[quantity])}")
    return unit


def _pick(columns: dict[str, str | None], wanted: str | None, candidates: Sequence[str], quantity: str,
          source: str) -> tuple[str, str]:
    if wanted is not None:
        if wanted not in columns:
            raise OptimizerError(f"{source}: no column '{wanted}' (columns: {', '.join(columns)})")
        return wanted, _unit(wanted, columns[wanted], quantity, source)
    for base in candidates:
        for name in columns:
            suffix = name[len(base) + 1:] if name.startswith(base + "_") else None
            if name == base or suffix in UNITS[quantity]:
                return name, _unit(name, columns[name], quantity, source)
    raise OptimizerError(f"{source}: no {quantity} column (looked for {', '.join(candidates)}; it has "
                         f"{', '.join(columns) or 'none'}); name it with --{quantity}-column")


def read_recording(path: str | Path, *, time_column: str | None = None, angle_column: str | None = None,
                   thrust_column: str | None = None) -> Recording:
    """Read one run (a CSV, or a `run --out` directory); refuse it with one line if unusable."""
    path = Path(path)
    csv_path = path / "results.csv" if path.is_dir() else path
    source = str(path)
    if not csv_path.is_file():
        raise OptimizerError(f"{source}: no such file (give a CSV or a `featherstar run --out` directory)")
    try:
        with open(csv_path, newline="", encoding="utf-8") as handle:
            header = next(csv.reader(handle), [])
    except UnicodeDecodeError as exc:
        raise OptimizerError(f"{source}: not UTF-8 text (byte {exc.start} of its header); a recording is a CSV") from None
    except (csv.Error, OSError) as exc:
        raise OptimizerError(f"{source}: unreadable as CSV ({exc})") from None
    columns: dict[str, str | None] = {}
    for cell in header:
        match = _HEADER.match(cell)
        if match:
            columns[match["name"]] = match["unit"]
    names = list(columns)
    picked = [_pick(columns, time_column, TIME_NAMES, "time", source),
              _pick(columns, angle_column, ANGLE_NAMES, "angle", source),
              _pick(columns, thrust_column, THRUST_NAMES, "thrust", source)]
    try:
        data = np.loadtxt(csv_path, delimiter=",", skiprows=1, ndmin=2, encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise OptimizerError(f"{source}: not UTF-8 text (byte {exc.start}); a recording is a CSV") from None
    except ValueError as exc:
        raise OptimizerError(f"{source}: not a numeric CSV below its header ({' '.join(str(exc).split())})") from None
    if data.shape[0] < 8 or data.shape[1] != len(names):
        raise OptimizerError(f"{source}: {data.shape[0]} rows of {data.shape[1]} values under {len(names)} "
                             "columns; a run needs at least 8 complete rows")
    (t, t_unit), (a, a_unit), (f, f_unit) = [(data[:, names.index(n)], u) for n, u in picked]
    if not np.all(np.isfinite(data[:, [names.index(n) for n, _ in picked]])):
        raise OptimizerError(f"{source}: NaN or inf in the time, angle or thrust column")
    t = (t - t[0]) * UNITS["time"][t_unit]
    if not np.all(np.diff(t) > 0):
        raise OptimizerError(f"{source}: time does not increase strictly")
    period, complete, reason = None, None, ""
    summary = (path if path.is_dir() else path.parent) / "summary.json"
    if summary.is_file():
        try:
            stored = json.loads(summary.read_bytes().decode("utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise OptimizerError(f"{summary}: unreadable ({exc}); fix or remove it, or give --window-s") from None
        stored = stored if isinstance(stored, dict) else {}
        period = stored.get("period_s")
        if isinstance(stored.get("complete"), bool):
            complete = stored["complete"]
            reason = str(stored.get("incomplete_reason", "")) if not complete else ""
        if period is not None and not (isinstance(period, (int, float)) and math.isfinite(period) and period > 0):
            raise OptimizerError(f"{summary}: period_s = {period!r} is not a positive number of seconds")
    return Recording(source, t, a * UNITS["angle"][a_unit], f * UNITS["thrust"][f_unit], (t_unit, a_unit, f_unit),
                     float(period) if period else None, complete, reason)


def check_same_stroke(recordings: Sequence[Recording], window_s: float) -> None:
    """Refuse runs whose units differ or whose root angles differ within the fit window."""
    first = recordings[0]
    for other in recordings[1:]:
        if other.units != first.units:
            raise OptimizerError(
                f"{other.source}: time, angle, thrust in {'/'.join(other.units)} but {first.source} in "
                f"{'/'.join(first.units)}; the runs of one calibration must use the same units")
        if first.period_s and other.period_s and not math.isclose(first.period_s, other.period_s, rel_tol=1e-6):
            raise OptimizerError(f"{other.source}: stroke period {other.period_s:g} s, {first.source}: "
                                 f"{first.period_s:g} s; the runs of one calibration must repeat one stroke")
        grid = np.linspace(0.0, window_s, 200)
        if other.time_s[-1] < window_s or first.time_s[-1] < window_s:
            continue   # check_window says it, with the run that is too short
        reference = np.interp(grid, first.time_s, first.angle_rad)
        deviation = np.max(np.abs(np.interp(grid, other.time_s, other.angle_rad) - reference))
        limit = max(STROKE_TOLERANCE_FRACTION * np.ptp(reference), STROKE_TOLERANCE_MIN_RAD)
        if deviation > limit:
            raise OptimizerError(
                f"{other.source}: its root angle differs from {first.source}'s by up to "
                f"{math.degrees(deviation):.1f}° in the fit window (limit {math.degrees(limit):.1f}°); "
                "the runs of one calibration must repeat one stroke")
