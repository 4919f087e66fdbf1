"""Which stroke periods of a real-time (hardware-in-the-loop) run can be trusted.

A paced run records what the bench did at each step, but a step that started late ran the bench
on a stale setpoint, a device that recovered from a fault left a hole in the data, and a load
cell that reconnected may have rebooted and lost its tare (the feather is moving, so it cannot
be tared again). Such periods are excluded from TR and mean thrust and listed in the summary.

A metric period is invalid when, inside it,
  - a step started more than MAX_LATE_S late (a stall: the bench ran open-loop), or
  - more than MAX_MISS_FRACTION of its steps missed their deadline (started > 1 step late), or
  - a device needed a recovery (a data gap), or
  - a device reported its plant behind real time (an emulator's status lag bit: its data lag
    the clock by more than its limit), or
  - a device restarted (its [session] boot id changed, featherstar.hil.session; behind a
    gateway the connection stays up) or reconnected, and, for the load cell, every period at
    or after it (the tare is unknown until the end of the run).
A run is complete only if at least MIN_VALID_FRACTION of the window's periods (and at least
one) are valid; otherwise `complete` is false and `featherstar run` exits with status 2.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from .metrics import thrust_metrics

MAX_LATE_S = 0.05          # 12 steps at 250 Hz: the servo can travel 0.3 rad on a stale command
MAX_MISS_FRACTION = 0.1    # isolated misses of a loaded machine are jitter, a tenth is not
MIN_VALID_FRACTION = 0.5   # fewer valid periods than this share of the window: not a result
# Events after which the device may not be the one that was tared and enabled at the start.
_RESTARTS = {"reconnect": "reconnected", "restart": "restarted (new boot id)"}


@dataclass(frozen=True)
class PeriodVerdict:
    index: int                 # 0-based period of the metric window
    start_s: float
    reasons: tuple[str, ...]   # empty = valid


def judge_periods(window_s: Sequence[float], period_s: float, n_periods: int, step_s: float,
                  late_steps: Sequence[tuple[float, float]],
                  events: Sequence[Mapping[str, Any]]) -> list[PeriodVerdict]:
    """One verdict per period of the window; late_steps = (t_s, lateness_s) of deadline misses."""
    a = float(window_s[0])
    steps_per_period = max(1, round(period_s / step_s))
    verdicts = []
    for k in range(n_periods):
        ta, tb = a + k * period_s, a + (k + 1) * period_s
        reasons: list[str] = []
        late = [s for t, s in late_steps if ta <= t < tb]
        if late and max(late) > MAX_LATE_S:
            reasons.append(f"a step started {max(late):.3f} s late (limit {MAX_LATE_S} s)")
        if len(late) > MAX_MISS_FRACTION * steps_per_period:
            reasons.append(f"{len(late)} of {steps_per_period} steps missed their deadline "
                           f"(limit {MAX_MISS_FRACTION:.0%})")
        for e in events:
            t = float(e.get("t_s", math.nan))
            if e.get("kind") == "gap" and ta <= t < tb:
                reasons.append(f"{e.get('device')}: data gap at t={t:.3f} s")
            elif e.get("kind") == "lag" and ta <= t < tb:
                reasons.append(f"{e.get('device')}: plant behind real time at t={t:.3f} s")
            elif e.get("kind") in _RESTARTS and e.get("tare_unknown") and t < tb:
                reasons.append(f"{e.get('device')}: {_RESTARTS[e['kind']]} at t={t:.3f} s, "
                               "tare unknown")
            elif e.get("kind") in _RESTARTS and ta <= t < tb:
                reasons.append(f"{e.get('device')}: {_RESTARTS[e['kind']]} at t={t:.3f} s")
        verdicts.append(PeriodVerdict(k, ta, tuple(reasons)))
    return verdicts


def valid_thrust_metrics(t: np.ndarray, thrust: np.ndarray, period_s: float,
                         verdicts: Sequence[PeriodVerdict]) -> dict[str, Any]:
    """TR and mean thrust over the valid periods only (NaN when there are none)."""
    pos = neg = 0.0
    n = 0
    for v in verdicts:
        if v.reasons:
            continue
        m = thrust_metrics(t, thrust, v.start_s, v.start_s + period_s, None, 0)
        pos, neg = pos + m["positive_impulse_Ns"], neg + m["negative_impulse_Ns"]
        n += 1
    if n == 0:
        return {"thrust_ratio": math.nan, "mean_thrust_N": math.nan}
    return {"thrust_ratio": pos / neg if neg > 0 else math.inf,
            "mean_thrust_N": (pos - neg) / (n * period_s)}


def apply_validity(summary: dict[str, Any], t: np.ndarray, thrust: np.ndarray | None,
                   period_s: float | None, step_s: float,
                   late_steps: Sequence[tuple[float, float]],
                   events: Sequence[Mapping[str, Any]]) -> bool:
    """Judge the periods of a finished real-time run, replace TR and mean thrust by their
    values over the valid periods, and record the verdict in `summary`; returns whether the run
    is complete (enough valid periods)."""
    n = int(summary.get("periods_used", 0) or 0)
    if not period_s or n == 0 or "window_s" not in summary:
        summary["validity"] = {"valid_periods": 0, "invalid_periods": [],
                               "reason": "no whole period in the metric window"}
        return False
    verdicts = judge_periods(summary["window_s"], period_s, n, step_s, late_steps, events)
    invalid = [{"period": v.index + 1, "start_s": v.start_s, "reasons": list(v.reasons)}
               for v in verdicts if v.reasons]
    n_valid = n - len(invalid)
    needed = max(1, math.ceil(MIN_VALID_FRACTION * n))
    summary["validity"] = {"valid_periods": n_valid, "invalid_periods": invalid,
                           "needed_valid_periods": needed,
                           "limits": {"max_late_s": MAX_LATE_S,
                                      "max_miss_fraction": MAX_MISS_FRACTION,
                                      "min_valid_fraction": MIN_VALID_FRACTION}}
    if invalid and thrust is not None:
        summary["thrust_ratio_all_periods"] = summary.get("thrust_ratio")
        summary["mean_thrust_N_all_periods"] = summary.get("mean_thrust_N")
        summary.update(valid_thrust_metrics(t, thrust, period_s, verdicts))
        for key in ("per_period_thrust_ratio", "per_period_mean_thrust_N"):
            if key in summary:   # keep the list aligned with the periods, invalid ones blanked
                summary[key] = [math.nan if verdicts[i].reasons else x
                                for i, x in enumerate(summary[key])]
    if n_valid < needed:
        summary["validity"]["reason"] = (f"only {n_valid} of {n} periods are valid, "
                                         f"{needed} needed")
        return False
    return True
