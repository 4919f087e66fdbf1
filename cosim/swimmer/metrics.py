"""The paper's metrics on recorded signals, over whole periods after a settling time.

mean thrust (Eq. 2)   T̄ = (1/W) ∫_W T dt
thrust ratio (Eq. 3)  TR = ∫_W T⁺ dt / ∫_W |T⁻| dt
robot mean speed      (x(end) − x(start)) / W from the body position (or the mean body speed)

W is the window of whole stroke periods after `settle_periods` periods of transient. Signals are
integrated as the piecewise-linear interpolant of the samples, split exactly at zero crossings,
so TR does not depend on where the samples fall relative to a sign change. Per-period values are
reported too: flapped feathers are chaotic (physics notes §9), judge them on windowed statistics.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np


def window(t_end: float, period: float | None, settle_periods: float, t0: float = 0.0) -> tuple[float, float, int]:
    """(start, stop, number of whole periods) of the metric window."""
    if not period:
        return t0, t_end, 0
    start = t0 + settle_periods * period
    n = int(math.floor((t_end - start) / period + 1e-9))
    if n <= 0:  # run too short for a settled whole period: use what is there
        return t0, t_end, 0
    return start, start + n * period, n


def _clip(t: np.ndarray, y: np.ndarray, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    mask = (t > a) & (t < b)
    tt = np.concatenate([[a], t[mask], [b]])
    yy = np.concatenate([[np.interp(a, t, y)], y[mask], [np.interp(b, t, y)]])
    return tt, yy


def signed_integrals(t: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(∫ y⁺ dt, ∫ |y⁻| dt) of the piecewise-linear interpolant."""
    dt = np.diff(t)
    y0, y1 = y[:-1], y[1:]
    pos = np.zeros_like(dt)
    neg = np.zeros_like(dt)
    both_pos = (y0 >= 0) & (y1 >= 0)
    both_neg = (y0 <= 0) & (y1 <= 0)
    pos[both_pos] = 0.5 * (y0 + y1)[both_pos] * dt[both_pos]
    neg[both_neg] = -0.5 * (y0 + y1)[both_neg] * dt[both_neg]
    cross = ~(both_pos | both_neg)
    if cross.any():
        a, b, h = y0[cross], y1[cross], dt[cross]
        frac = a / (a - b)  # where the segment crosses zero
        first = 0.5 * a * frac * h
        second = 0.5 * b * (1 - frac) * h
        pos[cross] = np.where(a > 0, first, second)
        neg[cross] = -np.where(a > 0, second, first)
    return float(pos.sum()), float(neg.sum())


def thrust_metrics(t: np.ndarray, thrust: np.ndarray, a: float, b: float, period: float | None,
                   n_periods: int) -> dict[str, Any]:
    tt, yy = _clip(t, thrust, a, b)
    pos, neg = signed_integrals(tt, yy)
    width = b - a
    out: dict[str, Any] = {
        "thrust_ratio": pos / neg if neg > 0 else math.inf,
        "mean_thrust_N": (pos - neg) / width if width > 0 else math.nan,
        "positive_impulse_Ns": pos,
        "negative_impulse_Ns": neg,
    }
    if period and n_periods >= 1:
        per_tr, per_mean = [], []
        for k in range(n_periods):
            ta, tb = a + k * period, a + (k + 1) * period
            pt, py = _clip(t, thrust, ta, tb)
            p, n = signed_integrals(pt, py)
            per_tr.append(p / n if n > 0 else math.inf)
            per_mean.append((p - n) / period)
        out["per_period_thrust_ratio"] = per_tr
        out["per_period_mean_thrust_N"] = per_mean
    return out


def speed_metrics(t: np.ndarray, a: float, b: float, position: np.ndarray | None,
                  speed: np.ndarray | None) -> dict[str, Any]:
    if position is not None:
        x0, x1 = np.interp([a, b], t, position)
        return {"mean_speed_m_s": float((x1 - x0) / (b - a)), "displacement_m": float(position[-1] - position[0])}
    tt, vv = _clip(t, speed, a, b)
    return {"mean_speed_m_s": float(np.trapezoid(vv, tt) / (b - a))}


def scene_metrics(metrics_spec: Any, period: float | None, t: np.ndarray,
                  signals: dict[str, np.ndarray]) -> dict[str, Any]:
    """The paper's metrics of a run as the scene's [metrics] table asks for them: the window of
    whole periods after settling, thrust (Eq. 2, Eq. 3) and the robot's speed."""
    a, b, k = window(float(t[-1]), period, metrics_spec.settle_periods, float(t[0]))
    out: dict[str, Any] = {"window_s": [a, b], "periods_used": k}
    if metrics_spec.thrust:
        out.update(thrust_metrics(t, signals[metrics_spec.thrust], a, b, period, k))
    if metrics_spec.position or metrics_spec.speed:
        out.update(speed_metrics(t, a, b, signals.get(metrics_spec.position) if metrics_spec.position else None,
                                 signals.get(metrics_spec.speed) if metrics_spec.speed else None))
    return out
