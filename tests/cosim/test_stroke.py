import math

import casadi as ca
import numpy as np
import pytest
from featherstar.cosim.swimmer.stroke import Stroke, root_motion, root_motion_symbolic, stroke_from_log_ratios
from featherstar.fmu_src.errors import ModelError


def test_log_ratios_round_trip():
    stroke = Stroke(t_up_s=0.1, t_hold_up_s=0.3, t_down_s=0.5, t_hold_down_s=0.6)
    again = stroke_from_log_ratios(stroke.period_s, *stroke.log_ratios())
    for name in ("t_up_s", "t_hold_up_s", "t_down_s", "t_hold_down_s"):
        assert getattr(again, name) == pytest.approx(getattr(stroke, name), rel=1e-12)


def test_symmetric_baseline_ratios():
    assert Stroke().log_ratios() == pytest.approx((0.0, 0.0, math.log10(2.0)))
    assert Stroke().period_s == pytest.approx(1.5)


def test_rate_and_accel_are_derivatives_of_angle():
    stroke = Stroke(t_up_s=0.2, t_hold_up_s=0.1, t_down_s=0.7, t_hold_down_s=0.5)
    t = np.linspace(0.0, 2 * stroke.period_s, 20001)
    angle, rate, accel = np.array([root_motion(stroke, ti) for ti in t]).T
    dt = t[1] - t[0]
    assert np.max(np.abs(np.gradient(angle, dt) - rate)) < 1e-3 * np.max(np.abs(rate))
    assert np.max(np.abs(np.gradient(rate, dt) - accel)) < 1e-2 * np.max(np.abs(accel))
    assert angle.min() == pytest.approx(-stroke.amplitude_rad / 2)
    assert angle.max() == pytest.approx(stroke.amplitude_rad / 2)


def test_symbolic_stroke_matches_numeric():
    stroke = Stroke(t_up_s=0.3, t_hold_up_s=0.2, t_down_s=0.6, t_hold_down_s=0.4, amplitude_deg=80)
    t = ca.SX.sym("t")
    f = ca.Function("m", [t], list(root_motion_symbolic(
        t, stroke.t_up_s, stroke.t_hold_up_s, stroke.t_down_s, stroke.t_hold_down_s, stroke.amplitude_rad)))
    for ti in np.linspace(0.0, 3.0, 301):
        assert np.array([float(v) for v in f(ti)]) == pytest.approx(root_motion(stroke, ti), abs=1e-9)


@pytest.mark.parametrize("field,value", [("t_up_s", 0.0), ("t_down_s", -1.0), ("t_hold_up_s", -0.1),
                                          ("amplitude_deg", 0.0), ("t_up_s", float("nan"))])
def test_bad_stroke_is_refused(field, value):
    with pytest.raises(ModelError, match=field):
        Stroke(**{field: value})


# --- the command a bench loop sends (controller sample_period_s, rate_limit_rad_s) -----------------

def test_sampled_command_holds_the_stroke_at_each_step_end_and_limits_its_rate():
    from featherstar.cosim.swimmer.controller import Command, StrokeController

    stroke = Stroke(t_up_s=0.1, t_hold_up_s=0.2, t_down_s=0.3, t_hold_down_s=0.4)
    held = StrokeController("c", stroke, Command(sample_period_s=0.01))
    held.start(0.0)
    for k in range(0, 200, 7):
        for t in (k * 0.01, k * 0.01 + 0.004, k * 0.01 + 0.0099):
            assert held.outputs_at(t) == (pytest.approx(root_motion(stroke, (k + 1) * 0.01)[0]), 0.0, 0.0)
        assert held.next_sample_s(k * 0.01 + 0.003) == pytest.approx((k + 1) * 0.01)
    limited = StrokeController("c", stroke, Command(sample_period_s=0.01, rate_limit_rad_s=6.2))
    limited.start(0.0)
    samples = np.array([limited.outputs_at(k * 0.01)[0] for k in range(300)])
    assert samples[0] == pytest.approx(-0.062)                    # from 0 rad, one limited step
    assert np.max(np.abs(np.diff(samples))) <= 0.062 + 1e-12
    # the 0.1 s upstroke asks 1.875 * 1.047 / 0.1 = 19.6 rad/s: the limit bites; the holds catch up
    assert np.max(np.abs(np.diff(samples))) == pytest.approx(0.062)
    assert samples[25] == pytest.approx(root_motion(stroke, 0.26)[0], abs=1e-12)


def test_strong_coupling_restarts_at_every_sample_and_converges_to_the_continuous_command():
    """A held command is a jump every sample: the solver stops there (one event per sample). The
    held command converges to the continuous one as the sample period shrinks, and so do the servo
    angle and the thrust it gives, at first order (the servo's position loop, a 30 ms lag, smooths
    the steps). The mean thrust is compared only to a bound: its difference is the mean of a
    signed error that cancels over the period (measured 0.9-7.7 uN of 31 mN, not monotonic)."""
    from featherstar.cosim.swimmer.run import run_scene

    base = {"feather.morphology": "chordwise", "controller.period_s": 1.0, "controller.log10_up_down": 0.6,
            "master.periods": 2, "metrics.settle_periods": 1}
    continuous = run_scene("testbed", base)
    angle_rms, thrust_rms = [], []
    for period_s in (0.004, 0.002, 0.001, 0.0005):
        result = run_scene("testbed", {**base, "controller.sample_period_s": period_s})
        assert result.summary["stats"]["events"] == pytest.approx(2.0 / period_s, abs=1)
        angle_rms.append(np.sqrt(np.mean((result["servo.angle_rad"] - continuous["servo.angle_rad"]) ** 2)))
        thrust_rms.append(np.sqrt(np.mean((result["feather.thrust_N"] - continuous["feather.thrust_N"]) ** 2)))
        assert result.summary["mean_thrust_N"] == pytest.approx(continuous.summary["mean_thrust_N"], rel=1e-3)
    # measured: angle 6.5, 3.3, 1.6, 0.84 mrad; thrust 10.2, 5.3, 2.8, 1.4 mN: ratios 1.9-2.0
    for errors in (angle_rms, thrust_rms):
        ratios = np.array(errors[:-1]) / np.array(errors[1:])
        assert np.all((ratios > 1.7) & (ratios < 2.3)), ratios


def test_a_rate_limit_without_sampling_is_refused():
    from featherstar.cosim.errors import SceneError
    from featherstar.cosim.swimmer.run import run_scene

    with pytest.raises(SceneError, match="'rate_limit_rad_s' limits a sampled command"):
        run_scene("testbed", {"controller.rate_limit_rad_s": 6.2})
