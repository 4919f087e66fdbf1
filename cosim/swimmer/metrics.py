"""The paper's metrics on recorded signals, over whole periods after a settling time.

mean thrust (Eq. 2)   T̄ = (1/W) ∫_W T dt
thrust ratio (Eq. 3)  TR = ∫_W T⁺ dt / ∫_W |T⁻| dt
robot mean speed      (x(end) − x(start)) / W from the body position (or the mean body speed)

W is the window of whole stroke periods after `settle_periods` periods of transient. Signals are
integrated as the piecewise-linear interpolant of the samples on the times they were taken
(any spacing), split exactly at zero crossings, so TR does not depend on where the samples fall
relative to a sign change. A signal whose block also records `t_read_s` (a streaming hardware
device: the PC's clock at each read, featherstar.hil.blocks.LoadCell) was taken then, not on the
master's step grid: a late read on a loaded PC is a sample of later thrust (`sample_times`).
Periods are windows of the run's time, whichever clock the samples carry. Per-period values are
reported too: flapped feathers are chaotic (physics notes §9), judge them on windowed statistics.

Each metric states what it needs (`preconditions`): a known period, at least one whole period in
the window, a period spanning MIN_SAMPLES_PER_PERIOD samples, finite samples, a negative impulse
for TR; a result is complete only when every one holds (featherstar.cosim.swimmer.run). The
metrics are still computed when one fails, so that the summary shows what went wrong.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..scene.preflight import MIN_SAMPLES_PER_PERIOD


@dataclass(frozen=True)
class Precondition:
    """One thing a metric needs of the recording; `reason` says why it fails ("" = it holds)."""

    name: str
    reason: str = ""

    @property
    def holds(self) -> bool:
        return not self.reason


READ_TIME_PORT = "t_read_s"


def sample_times(t: np.ndarray, signals: dict[str, np.ndarray], name: str) -> tuple[np.ndarray, Precondition | None]:
    """When the samples of signal `name` ("block.port") were taken: its block's recorded
    `t_read_s` if there is one, else the run's time grid `t`; with the precondition on the read
    times (finite, one per row, never decreasing), None when there are none."""
    read = signals.get(f"{name.rpartition('.')[0]}.{READ_TIME_PORT}")
    if read is None:
        return t, None
    read = np.asarray(read, dtype=float)
    check = f"read_times_{name.rpartition('.')[0]}"
    if read.shape != np.shape(t) or not np.all(np.isfinite(read)) or np.any(np.diff(read) < 0):
        bad = int(np.sum(~np.isfinite(read))) if read.shape == np.shape(t) else -1
        return t, Precondition(check, f"{name.rpartition('.')[0]}.{READ_TIME_PORT} is not a "
                                      f"finite, non-decreasing time per sample ({bad} non-finite)"
                                      if bad >= 0 else f"{READ_TIME_PORT}: {read.shape[0]} read "
                                      f"times for {np.shape(t)[0]} samples")
    return read, Precondition(check)


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


def window_preconditions(t: np.ndarray, a: float, b: float, period: float | None, n_periods: int,
                         settle_periods: float) -> list[Precondition]:
    """What every windowed metric needs: a period, a whole one after settling, enough samples in it."""
    if not period:
        return [Precondition("period_known", "no period: metrics.period_s = 0 and no stroke block gives "
                                             "one; the window is the whole run, transient included")]
    out = [Precondition("period_known")]
    if n_periods < 1:
        out.append(Precondition("whole_period_in_window",
                                f"the run of {float(t[-1] - t[0]):.4g} s holds no whole period of {period:.4g} s "
                                f"after settle_periods = {settle_periods:g}"))
    else:
        out.append(Precondition("whole_period_in_window"))
    inside = t[(t >= a) & (t <= b)]
    step = float(np.median(np.diff(inside))) if len(inside) > 1 else float(b - a)
    samples = period / step if step > 0 else 0.0
    out.append(Precondition("samples_per_period", "" if samples >= MIN_SAMPLES_PER_PERIOD else
                            f"a period of {period:.4g} s spans {samples:.3g} samples of {step:.4g} s; "
                            f"at least {MIN_SAMPLES_PER_PERIOD} are needed"))
    return out


def finite_precondition(name: str, t: np.ndarray, y: np.ndarray, a: float, b: float) -> Precondition:
    """The signal is finite over the window (the samples inside it and the two it interpolates at
    its ends)."""
    lo = max(int(np.searchsorted(t, a, side="right")) - 1, 0)
    hi = min(int(np.searchsorted(t, b, side="left")) + 1, len(t))
    bad = ~np.isfinite(np.asarray(y[lo:hi], dtype=float))
    if not bad.any():
        return Precondition(f"finite_{name}")
    first = float(t[lo + int(np.argmax(bad))])
    return Precondition(f"finite_{name}", f"{int(bad.sum())} non-finite {name} samples in the window "
                                          f"(the first at t = {first:.6g} s)")


def thrust_preconditions(metrics: dict[str, Any]) -> list[Precondition]:
    """TR (Eq. 3) needs a negative impulse; both thrust metrics need finite values."""
    neg = metrics.get("negative_impulse_Ns", math.nan)
    return [Precondition("negative_impulse", "" if neg > 0 else
                         "no negative thrust in the window: the thrust ratio (Eq. 3) is undefined"),
            finite_thrust_metrics(metrics)]


def finite_thrust_metrics(metrics: dict[str, Any]) -> Precondition:
    bad = [k for k in ("thrust_ratio", "mean_thrust_N") if not math.isfinite(metrics.get(k, math.nan))]
    return Precondition("finite_thrust_metrics", f"{', '.join(bad)} not finite" if bad else "")


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
    checks: list[Precondition] = []
    if metrics_spec.thrust or metrics_spec.position or metrics_spec.speed:
        checks += window_preconditions(t, a, b, period, k, metrics_spec.settle_periods)
    # per-period values only for periods the samples resolve (a period of 1e-9 s would be
    # billions of empty ones)
    resolved = all(c.holds for c in checks if c.name == "samples_per_period")
    if metrics_spec.thrust:
        thrust = signals[metrics_spec.thrust]
        t_thrust, read_check = sample_times(t, signals, metrics_spec.thrust)
        if read_check is not None:
            checks.append(read_check)
            out["thrust_times"] = (f"{metrics_spec.thrust.rpartition('.')[0]}.{READ_TIME_PORT}"
                                   if read_check.holds else "the step grid")
        checks.append(finite_precondition("thrust", t_thrust, thrust, a, b))
        with np.errstate(invalid="ignore", divide="ignore"):
            out.update(thrust_metrics(t_thrust, thrust, a, b, period, k if resolved else 0))
        checks += thrust_preconditions(out)
    if metrics_spec.position or metrics_spec.speed:
        name = metrics_spec.position or metrics_spec.speed
        checks.append(finite_precondition("position" if metrics_spec.position else "speed", t, signals[name], a, b))
        with np.errstate(invalid="ignore", divide="ignore"):
            out.update(speed_metrics(t, a, b, signals.get(metrics_spec.position) if metrics_spec.position else None,
                                     signals.get(metrics_spec.speed) if metrics_spec.speed else None))
        finite = math.isfinite(out["mean_speed_m_s"])
        checks.append(Precondition("finite_speed_metric", "" if finite else "mean_speed_m_s not finite"))
    out["preconditions"] = {c.name: c.reason or "holds" for c in checks}
    return out


def failed_preconditions(summary: dict[str, Any]) -> dict[str, str]:
    """The preconditions of a summary's metrics that do not hold, by name, with the reason."""
    return {name: reason for name, reason in (summary.get("preconditions") or {}).items() if reason != "holds"}


def judge_valid_periods(summary: dict[str, Any], t: np.ndarray, thrust: np.ndarray, period: float | None,
                        trusted: bool) -> None:
    """A real-time run's preconditions once featherstar.cosim.swimmer.validity has judged its
    periods: enough valid periods (and a valid tare), finite thrust over the valid periods only
    (an excluded period may hold a gap), finite TR and mean thrust over them."""
    checks = summary.setdefault("preconditions", {})
    validity = summary.get("validity") or {}
    checks["valid_periods"] = "holds" if trusted else validity.get("reason", "the periods were not judged")
    if not period or "window_s" not in summary or checks.get("samples_per_period") != "holds":
        return
    a = float(summary["window_s"][0])
    excluded = {int(p["period"]) for p in validity.get("invalid_periods", [])}
    valid = [k for k in range(int(summary.get("periods_used", 0) or 0)) if k + 1 not in excluded]
    bad = [finite_precondition("thrust", t, thrust, a + k * period, a + (k + 1) * period) for k in valid]
    bad = [c for c in bad if not c.holds]
    checks["finite_thrust"] = bad[0].reason if bad else "holds"
    with np.errstate(invalid="ignore"):
        neg = sum(thrust_metrics(t, thrust, a + k * period, a + (k + 1) * period, None, 0)["negative_impulse_Ns"]
                  for k in valid)
    negative = thrust_preconditions({"negative_impulse_Ns": neg})[0]
    checks[negative.name] = negative.reason or "holds"
    final = finite_thrust_metrics(summary)   # TR and mean thrust over the valid periods
    checks[final.name] = final.reason or "holds"
