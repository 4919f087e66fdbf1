"""featherstar.cosim.swimmer.validity: which periods of a real-time run count, on synthetic signals and events."""
from __future__ import annotations

import math

import numpy as np
import pytest
from featherstar.cosim.swimmer.metrics import thrust_metrics
from featherstar.cosim.swimmer.report import summary_table
from featherstar.cosim.swimmer.validity import MAX_LATE_S, apply_validity, judge_periods

PERIOD_S, STEP_S = 1.0, 0.01


def _thrust(t: np.ndarray) -> np.ndarray:
    # Positive lobe twice the negative one: TR = 2 in every clean period.
    return np.where(np.sin(2 * np.pi * t) > 0, 2.0, -1.0) * np.abs(np.sin(2 * np.pi * t))


def _summary(n: int) -> dict:
    return {"window_s": [1.0, 1.0 + n], "periods_used": n, "thrust_ratio": 2.0,
            "mean_thrust_N": 0.3, "per_period_thrust_ratio": [2.0] * n}


def test_clean_run_keeps_every_period():
    t = np.arange(0, 5.0 + STEP_S / 2, STEP_S)
    summary = _summary(4)
    assert apply_validity(summary, t, _thrust(t), PERIOD_S, STEP_S, [], [])
    assert summary["validity"]["valid_periods"] == 4 and summary["validity"]["invalid_periods"] == []
    assert summary["thrust_ratio"] == 2.0          # untouched


def test_a_stall_and_a_gap_exclude_their_periods_and_the_metrics_use_the_rest():
    t = np.arange(0, 5.0 + STEP_S / 2, STEP_S)
    thrust = _thrust(t)
    thrust[(t >= 2.0) & (t < 3.0)] = -5.0           # what a stall does to the reading
    summary = _summary(4)
    late = [(2.5, 2 * MAX_LATE_S)]
    events = [{"t_s": 3.2, "kind": "gap", "device": "servo", "detail": "timeout"}]
    assert apply_validity(summary, t, thrust, PERIOD_S, STEP_S, late, events)
    invalid = {p["period"]: p["reasons"] for p in summary["validity"]["invalid_periods"]}
    assert sorted(invalid) == [2, 3]
    assert "late" in invalid[2][0] and "data gap" in invalid[3][0]
    # The clean periods 1 and 4, integrated on their own, give the reported values.
    clean = [thrust_metrics(t, thrust, a, a + PERIOD_S, PERIOD_S, 1) for a in (1.0, 4.0)]
    pos = sum(c["positive_impulse_Ns"] for c in clean)
    neg = sum(c["negative_impulse_Ns"] for c in clean)
    assert summary["thrust_ratio"] == pytest.approx(pos / neg, rel=1e-12)
    assert summary["mean_thrust_N"] == pytest.approx((pos - neg) / 2.0, rel=1e-12)
    assert summary["thrust_ratio"] == pytest.approx(2.0, rel=0.05)
    assert summary["thrust_ratio_all_periods"] == 2.0
    assert math.isnan(summary["per_period_thrust_ratio"][1])


def test_a_load_cell_reconnect_invalidates_every_later_period_and_the_run():
    t = np.arange(0, 5.0 + STEP_S / 2, STEP_S)
    summary = _summary(4)
    events = [{"t_s": 2.1, "kind": "reconnect", "device": "cell", "tare_unknown": True}]
    assert not apply_validity(summary, t, _thrust(t), PERIOD_S, STEP_S, [], events)
    assert [p["period"] for p in summary["validity"]["invalid_periods"]] == [2, 3, 4]
    assert "only 1 of 4 periods are valid, 2 needed" in summary["validity"]["reason"]
    summary.update(deadline_misses=3, worst_lateness_s=0.2, reconnects=1,
                   incomplete_reason=summary["validity"]["reason"])
    text = summary_table(summary)
    for expected in ("deadline misses", "reconnects", "excluded period 2", "INCOMPLETE"):
        assert expected in text


def test_scattered_misses_below_the_fraction_are_jitter_above_it_not():
    steps = round(PERIOD_S / STEP_S)
    few = [(1.0 + i * 0.05, 0.02) for i in range(steps // 20)]
    many = [(2.0 + i * 0.005, 0.02) for i in range(steps // 5)]
    verdicts = judge_periods([1.0, 3.0], PERIOD_S, 2, STEP_S, few + many, [])
    assert verdicts[0].reasons == () and "missed their deadline" in verdicts[1].reasons[0]
