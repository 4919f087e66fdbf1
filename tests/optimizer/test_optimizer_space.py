import math

import numpy as np
import pytest
from featherstar.cosim.swimmer.stroke import stroke_from_log_ratios
from featherstar.optimizer.errors import OptimizerError
from featherstar.optimizer.space import (
    LOG_HOLD_MOVE,
    LOG_UP_DOWN,
    STROKE_VARIABLES,
    ServoLimits,
    Variable,
    stroke_space,
    symmetric_stroke,
)


def test_servo_bounds_the_shortest_ramp():
    # min-jerk peak rate 1.875·A/t must stay below 6.2 rad/s: 60° → 0.3167 s
    assert ServoLimits().min_ramp_s(60.0) == pytest.approx(1.875 * math.radians(60) / 6.2)
    assert ServoLimits().min_ramp_s(60.0) == pytest.approx(0.3167, abs=1e-4)


@pytest.mark.parametrize("period_s", [1.5, 3.0])
def test_box_is_the_hull_of_servo_feasible_strokes(period_s):
    space = stroke_space(period_s)
    rng = np.random.default_rng(0)
    X = space.sample(rng, 3000)
    low, high = np.array(space.bounds).T
    # every bound is reached by some feasible stroke: the box is tight
    assert np.all(X.min(axis=0) - low < 0.1 * (high - low))
    assert np.all(high - X.max(axis=0) < 0.1 * (high - low))
    min_ramp_s = ServoLimits().min_ramp_s(60.0)
    for row in X[:300]:
        stroke = space.stroke(space.point(row))
        assert stroke.period_s == pytest.approx(period_s)
        assert min(stroke.t_up_s, stroke.t_down_s) >= min_ramp_s * (1 - 1e-9)
        assert stroke.peak_rate_rad_s() <= 6.2 * (1 + 1e-9)


def test_vectorized_feasibility_matches_the_scalar_check():
    space = stroke_space(1.5)
    low, high = np.array(space.bounds).T
    X = low + (high - low) * np.random.default_rng(1).random((2000, 3))
    mask = space.feasible_mask(X)
    assert 0.1 < mask.mean() < 0.9  # the servo limit really cuts the box
    assert all(mask[i] == space.is_feasible(space.point(X[i])) for i in range(len(X)))


def test_overrides_carry_the_stroke_times():
    space = stroke_space(1.5)
    point = {LOG_UP_DOWN: 0.2, "log10_hold_up_down": -0.5, LOG_HOLD_MOVE: -0.4}
    stroke = stroke_from_log_ratios(1.5, 0.2, -0.5, -0.4)
    overrides = space.overrides(point)
    assert overrides["controller.t_up_s"] == pytest.approx(stroke.t_up_s)
    assert overrides["controller.t_hold_down_s"] == pytest.approx(stroke.t_hold_down_s)
    assert overrides["controller.amplitude_deg"] == 60.0


def test_paper_baseline_asks_more_than_the_servo_can_at_60_degrees():
    space = stroke_space(1.5)
    assert symmetric_stroke(1.5).t_up_s == pytest.approx(0.25)
    point = dict(zip(STROKE_VARIABLES, (0.0, 0.0, math.log10(2.0))))
    assert not space.is_feasible(point)
    # at a smaller amplitude the same stroke is within the servo's reach
    assert stroke_space(1.5, amplitude_deg=40.0).is_feasible(point)


def test_period_shorter_than_the_servo_allows_is_refused():
    with pytest.raises(OptimizerError, match=r"period 0.5 s is shorter than the servo allows.*>= 0.673 s"):
        stroke_space(0.5)


def test_inverted_bounds_are_refused():
    with pytest.raises(OptimizerError, match="inverted"):
        stroke_space(1.5, bounds={LOG_UP_DOWN: (0.3, -0.3)})
    with pytest.raises(OptimizerError, match="inverted"):
        Variable("feather.width_ratio", 12.0, 1.5)


def test_unknown_variable_is_refused_with_a_suggestion():
    with pytest.raises(OptimizerError, match=r"unknown variable 'log10_up_dwn'.*did you mean 'log10_up_down'"):
        stroke_space(1.5, bounds={"log10_up_dwn": (-0.1, 0.1)})
    space = stroke_space(1.5)
    with pytest.raises(OptimizerError, match=r"unknown \['t_up'\]"):
        space.overrides({**dict.fromkeys(STROKE_VARIABLES, 0.0), "t_up": 0.1})


def test_bounds_beyond_the_servo_are_refused():
    with pytest.raises(OptimizerError, match="exceed what the servo allows"):
        stroke_space(1.5, bounds={LOG_UP_DOWN: (-1.0, 1.0)})


def test_narrowed_box_without_any_feasible_stroke_is_refused():
    low, high = stroke_space(1.5).bounds[0]
    with pytest.raises(OptimizerError, match="no feasible stroke"):
        stroke_space(1.5, bounds={LOG_UP_DOWN: (high - 0.01, high), LOG_HOLD_MOVE: (0.1, 0.136)})


def test_extra_variables_pass_through():
    space = stroke_space(1.5, extra=[Variable("feather.width_ratio", 1.5, 12.0)])
    point = {**dict(zip(STROKE_VARIABLES, (0.0, 0.0, -0.3))), "feather.width_ratio": 7.5}
    assert space.overrides(point)["feather.width_ratio"] == 7.5
    with pytest.raises(OptimizerError, match="repeat a name"):
        stroke_space(1.5, extra=[Variable(LOG_UP_DOWN, 0.0, 1.0)])


def test_public_api_is_exported():
    from featherstar import optimizer

    assert sorted(optimizer.__all__) == sorted(set(optimizer.__all__))
    for name in optimizer.__all__:
        assert hasattr(optimizer, name), name
    assert issubclass(optimizer.OptimizerError, __import__("featherstar.fmu_src.errors").fmu_src.errors.FeatherstarError)
