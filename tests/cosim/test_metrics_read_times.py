"""Metrics on the times the samples were taken (issue 25): a streaming load cell read late by a
loaded PC recorded later thrust than its step says. With its `t_read_s` recorded, TR and mean
thrust of T(t) = c + sin(2πt/P) come out at their analytic values whatever the read clock's
jitter; on the step grid they are off by exactly the jitter's effect (the thrust seen through
the jittered clock, τ ↦ T(τ + d(τ)))."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from featherstar.cosim.swimmer.metrics import sample_times, scene_metrics
from featherstar.cosim.swimmer.validity import apply_validity

PERIOD_S, STEP_S, T_END_S = 1.0, 0.004, 4.2   # window: periods 2-4 (one settling period)


def _spec():
    return SimpleNamespace(thrust="lc.thrust_N", position="", speed="", settle_periods=1.0)


def _thrust(t, c):
    return c + np.sin(2 * np.pi * t / PERIOD_S)


def _analytic(c: float) -> tuple[float, float]:
    """(TR, mean thrust) of c + sin over whole periods: positive where sin θ > -c."""
    beta = math.asin(c)
    pos = c * (math.pi + 2 * beta) + 2 * math.cos(beta)    # ∫ (c + sin θ)⁺ dθ over 2π
    return pos / (pos - 2 * math.pi * c), c


def _read_clock(grid, amplitude_s, phase, late_s):
    """A PC that reads late by d(τ) = A sin(2πτ/P + φ) (its load follows the stroke) plus
    up to 0.2 steps of scatter."""
    return grid + amplitude_s * np.sin(2 * np.pi * grid / PERIOD_S + phase) + late_s


def _jittered(c, amplitude_s, phase, seed):
    grid = np.arange(0.0, T_END_S + STEP_S / 2, STEP_S)
    late_s = np.random.default_rng(seed).uniform(0.0, 0.2 * STEP_S, grid.shape)
    t_read = _read_clock(grid, amplitude_s, phase, late_s)
    return grid, t_read, _thrust(t_read, c)


@settings(max_examples=40, deadline=None)
@given(c=st.floats(-0.5, 0.5), amplitude_s=st.floats(0.0, 0.05), phase=st.floats(0.0, 2 * math.pi),
       seed=st.integers(0, 2**16))
def test_metrics_on_read_times_are_analytic_and_the_grid_is_off_by_the_jitter(c, amplitude_s, phase, seed):
    grid, t_read, thrust = _jittered(c, amplitude_s, phase, seed)
    assert np.all(np.diff(t_read) > 0)
    tr, mean = _analytic(c)
    on_read = scene_metrics(_spec(), PERIOD_S, grid, {"lc.thrust_N": thrust, "lc.t_read_s": t_read})
    assert on_read["thrust_times"] == "lc.t_read_s" and on_read["preconditions"]["read_times_lc"] == "holds"
    assert on_read["thrust_ratio"] == pytest.approx(tr, rel=1e-3)   # the interpolant's error
    assert on_read["mean_thrust_N"] == pytest.approx(mean, abs=2e-4)
    assert all(x == pytest.approx(tr, rel=2e-3) for x in on_read["per_period_thrust_ratio"])
    # The step grid's answer is the thrust seen through the jittered clock (the scatter's
    # mean, 0.1 step, included), integrated finely: the jitter's effect, and nothing else.
    on_grid = scene_metrics(_spec(), PERIOD_S, grid, {"lc.thrust_N": thrust})
    fine = np.arange(0.0, T_END_S, STEP_S / 20)
    seen = _thrust(_read_clock(fine, amplitude_s, phase, 0.1 * STEP_S), c)
    expected = scene_metrics(_spec(), PERIOD_S, fine, {"lc.thrust_N": seen})
    assert on_grid["thrust_ratio"] == pytest.approx(expected["thrust_ratio"], rel=2e-3)
    assert on_grid["mean_thrust_N"] == pytest.approx(expected["mean_thrust_N"], abs=1e-3)


def test_a_load_that_follows_the_stroke_biases_the_grid_by_percent_not_the_read_times():
    # reads 30 ms late at most, latest a quarter period in (the PC busiest on the up-stroke)
    grid, t_read, thrust = _jittered(0.3, 0.03, math.pi / 2, seed=1)
    tr, mean = _analytic(0.3)
    on_grid = scene_metrics(_spec(), PERIOD_S, grid, {"lc.thrust_N": thrust})
    on_read = scene_metrics(_spec(), PERIOD_S, grid, {"lc.thrust_N": thrust, "lc.t_read_s": t_read})
    assert on_grid["thrust_ratio"] / tr - 1 > 0.2
    assert abs(on_read["thrust_ratio"] / tr - 1) < 2e-4


def test_the_valid_periods_are_measured_on_the_read_times_too():
    grid, t_read, thrust = _jittered(0.3, 0.03, 0.0, seed=2)
    signals = {"lc.thrust_N": thrust, "lc.t_read_s": t_read}
    summary = scene_metrics(_spec(), PERIOD_S, grid, signals)
    gap = [{"t_s": 1.5, "kind": "gap", "device": "lc"}]   # period 1 of the window excluded
    t_thrust, check = sample_times(grid, signals, "lc.thrust_N")
    assert check.holds and np.array_equal(t_thrust, t_read)
    assert apply_validity(summary, t_thrust, thrust, PERIOD_S, STEP_S, [], gap)
    assert summary["validity"]["valid_periods"] == 2
    assert summary["thrust_ratio"] == pytest.approx(_analytic(0.3)[0], rel=2e-4)


@pytest.mark.parametrize("bad, words", [(lambda t: t[::-1], "non-decreasing"),
                                        (lambda t: np.where(t > 2, np.nan, t), "non-finite"),
                                        (lambda t: t[:-1], "read times for")])
def test_read_times_that_are_not_a_clock_make_the_result_incomplete(bad, words):
    grid, t_read, thrust = _jittered(0.3, 0.0, 0.0, seed=3)
    summary = scene_metrics(_spec(), PERIOD_S, grid, {"lc.thrust_N": thrust, "lc.t_read_s": bad(t_read)})
    assert words in summary["preconditions"]["read_times_lc"]
    assert summary["thrust_times"] == "the step grid"


def test_without_read_times_the_grid_is_the_clock():
    grid, _, thrust = _jittered(0.3, 0.0, 0.0, seed=4)
    summary = scene_metrics(_spec(), PERIOD_S, grid, {"lc.thrust_N": thrust})
    assert "thrust_times" not in summary and "read_times_lc" not in summary["preconditions"]
