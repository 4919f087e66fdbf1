"""The trajectory a device-timed run uploads (`trajectory_samples`): where the servo is first,
then the streaming servo block's commands, step by step."""
import math

from hypothesis import given
from hypothesis import strategies as st

from featherstar.hil.timed_run import trajectory_samples

STEP_S, RATE_RAD_S = 0.005, 6.2


def clamp(x: float) -> float:
    return min(max(x, -1.5), 1.5)


angles = st.floats(-2.0, 2.0, allow_nan=False)


@given(angles, st.lists(angles, min_size=1, max_size=60))
def test_sample_zero_is_where_the_servo_is_and_no_step_beats_the_rate_limit(present_rad, target_rad):
    samples = trajectory_samples(present_rad, target_rad, RATE_RAD_S, STEP_S, clamp)
    assert len(samples) == len(target_rad) and samples[0] == present_rad
    assert all(abs(b - a) <= RATE_RAD_S * STEP_S + 1e-12 for a, b in zip(samples, samples[1:]))


def test_a_reachable_stroke_is_played_sample_for_sample():
    # from t_k the servo holds the stroke at t_k (a streamed run's setpoints on its record's time axis)
    target_rad = [0.4 * math.sin(2 * math.pi * k * STEP_S) for k in range(400)]
    samples = trajectory_samples(0.0, target_rad, RATE_RAD_S, STEP_S, clamp)
    assert samples[1:] == [clamp(x) for x in target_rad[1:]]


def test_a_stroke_starting_away_from_rest_is_approached_at_the_rate_limit_after_time_zero():
    samples = trajectory_samples(0.0, [-1.309] * 10, RATE_RAD_S, STEP_S, clamp)
    assert samples[:4] == [0.0, -0.031, -0.062, -0.093] or all(
        math.isclose(a, b, abs_tol=1e-12) for a, b in zip(samples[:4], [0.0, -0.031, -0.062, -0.093]))
