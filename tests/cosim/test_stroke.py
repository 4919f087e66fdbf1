import math

import casadi as ca
import numpy as np
import pytest

from featherstar.cosim.stroke import Stroke, root_motion, root_motion_symbolic, stroke_from_log_ratios
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
