"""The feather, servo and robot equations against physics: analytic limits, conservation,
symmetry and Euler–Bernoulli beam theory. Integrated directly with CasADi (no FMU)."""
import math

import casadi as ca
import numpy as np
import pytest
from featherstar.cosim.swimmer.stroke import Stroke, root_motion_symbolic
from featherstar.fmu_src.catalog import build_model
from featherstar.fmu_src.errors import ModelError
from featherstar.fmu_src.feather import feather_model
from featherstar.fmu_src.fourbar import check_linkage, rocker_angle
from featherstar.fmu_src.integrate import integrate


def stroke_drive(stroke: Stroke, flow_speed_m_s: float = 0.0):
    def drive(t):
        angle, rate, accel = root_motion_symbolic(
            t, stroke.t_up_s, stroke.t_hold_up_s, stroke.t_down_s, stroke.t_hold_down_s, stroke.amplitude_rad)
        return ca.vertcat(angle, rate, accel, flow_speed_m_s)
    return drive


def thrust_ratio(thrust, dt):
    return np.sum(thrust[thrust > 0]) * dt / (-np.sum(thrust[thrust < 0]) * dt)


def run_stroke(model, stroke, parameters=None, periods=6, settle=3, per_period=600, rtol=1e-7):
    grid = np.linspace(0, periods * stroke.period_s, periods * per_period + 1)
    _, outputs = integrate(model, grid, stroke_drive(stroke), parameters, rtol=rtol, atol=1e-9)
    window = grid >= settle * stroke.period_s - 1e-12
    return grid[window], outputs[window]


def test_rigid_drag_only_plate_gives_time_ratio():
    stroke = Stroke(t_up_s=0.2, t_hold_up_s=0.3, t_down_s=0.4, t_hold_down_s=0.3)
    # Massless links (no structure, no added mass) must have undamped joints: with the sheet's
    # damping c a massless link's joint is a lag of time constant I/c -> 0, a singular limit.
    rigid = {"youngs_modulus_Pa": 1e10, "thickness_m": 5e-3, "solid_density_kg_m3": 1.0,
             "added_mass_scale": 0.0, "gravity_m_s2": 0.0, "oscillatory_drag": 0.0, "retardation_time_s": 0.0}
    t, y = run_stroke(feather_model("plain", 2), stroke, rigid, periods=2, settle=1, per_period=1500)
    assert thrust_ratio(y[:, 0], t[1] - t[0]) == pytest.approx(stroke.t_up_s / stroke.t_down_s, rel=0.01)
    # Stroke impulse of a rigid plate with minimum-jerk ramps (spec §7), weighted by cos θ.
    params = feather_model("plain", 2).default_parameters()
    w, l, rho, cn = params["width_m"], params["length_m"], 1000.0, params["drag_coeff"]
    amp = stroke.amplitude_rad
    tau = np.linspace(0, 1, 20001)
    ds = 30 * tau**2 * (1 - tau) ** 2
    angle = amp * (tau**3 * (10 - 15 * tau + 6 * tau**2) - 0.5)
    impulse = 0.5 * rho * cn * w * l**3 / 3 * np.trapezoid((amp * ds / stroke.t_down_s) ** 2 * np.cos(angle), tau * stroke.t_down_s)
    positive = np.sum(y[:, 0][y[:, 0] > 0]) * (t[1] - t[0])
    assert positive == pytest.approx(impulse, rel=0.02)


def test_bending_frequencies_in_air_match_euler_bernoulli():
    model = feather_model("plain", 10)
    air = {"water_density_kg_m3": 1e-9, "gravity_m_s2": 0.0, "retardation_time_s": 0.0}  # undamped frequencies
    xdot = model.function()(model.x, [0, 0, 0, 0], model.parameter_vector(air))[0]
    linear = np.array(ca.Function("A", [model.x], [ca.jacobian(xdot, model.x)])(np.zeros(model.x.numel())))
    omega = np.sort(np.abs(np.linalg.eigvals(linear).imag))[::2]
    values = model.default_parameters()
    ei = values["youngs_modulus_Pa"] * values["width_m"] * values["thickness_m"] ** 3 / 12
    m_per_length = values["solid_density_kg_m3"] * values["width_m"] * values["thickness_m"]
    for beta_l, computed in zip((1.87510, 4.69409), omega[:2]):
        exact = beta_l**2 * math.sqrt(ei / (m_per_length * values["length_m"] ** 4))
        assert computed == pytest.approx(exact, rel=0.02)


def test_plain_feather_symmetric_stroke_is_symmetric():
    t, y = run_stroke(feather_model("plain"), Stroke())
    assert 0.9 <= thrust_ratio(y[:, 0], t[1] - t[0]) <= 1.1


def test_fourbar_closes_its_loop_and_parallelogram_copies_input():
    a, b, c, d = 0.025, 0.062, 0.03, 0.06
    for theta2 in np.linspace(math.pi / 2 - 0.8, math.pi / 2 + 0.8, 17):
        theta4 = float(rocker_angle(theta2, a, b, c, d))
        crank_tip = np.array([a * math.cos(theta2), a * math.sin(theta2)])
        rocker_tip = np.array([d + c * math.cos(theta4), c * math.sin(theta4)])
        assert abs(np.linalg.norm(rocker_tip - crank_tip) - b) < 1e-12
    for theta2 in np.linspace(0.6, 2.5, 9):
        copied = float(rocker_angle(theta2, 0.03, 0.06, 0.03, 0.06))
        assert math.remainder(copied - theta2, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)


def test_robot_root_rate_and_accel_are_exact_derivatives():
    robot = build_model("robot")
    f = robot.function()
    p = robot.parameter_vector()
    def root(th):
        return float(f([0, 0], [th, 0, 0, 0, 0, 0, 0, 0, 0], p)[1][0])
    th, w, al, h = 0.3, 1.7, -4.0, 1e-5
    y = np.array(f([0, 0], [th, w, al, 0, 0, 0, 0, 0, 0], p)[1]).ravel()
    gain = (root(th + h) - root(th - h)) / (2 * h)
    slope = (root(th + h) - 2 * root(th) + root(th - h)) / h**2
    assert y[1] == pytest.approx(gain * w, rel=1e-6)
    assert y[2] == pytest.approx(slope * w**2 + gain * al, rel=1e-4)


@pytest.mark.parametrize("links", [(0.05, 0.02, 0.02, 0.06), (0.025, 0.062, 0.03, 0.2)])
def test_non_grashof_or_badly_conditioned_linkage_is_refused(links):
    with pytest.raises(ModelError, match="four-bar"):
        check_linkage(*links, math.pi / 2, math.radians(45))
    with pytest.raises(ModelError, match="four-bar"):
        build_model("robot").parameter_vector(dict(zip(("crank_m", "coupler_m", "rocker_m", "ground_m"), links)))


@pytest.mark.parametrize("kind,options,parameter,value,pattern", [
    ("feather", {"morphology": "plain"}, "length_m", -0.1, "length_m.*valid range"),
    ("feather", {"morphology": "chordwise"}, "width_ratio", 1.0, "width_ratio.*valid range"),
    ("feather", {"morphology": "spanwise"}, "length_ratio", 0.5, "length_ratio.*valid range"),
    ("feather", {"morphology": "plain"}, "drag_coeff", float("nan"), "drag_coeff"),
    ("servo", {}, "stall_torque_Nm", 0.0, "stall_torque_Nm"),
    ("robot", {}, "body_mass_kg", -1.0, "body_mass_kg"),
])
def test_non_physical_parameters_are_refused(kind, options, parameter, value, pattern):
    with pytest.raises(ModelError, match=pattern):
        build_model(kind, options).parameter_vector({parameter: value})


@pytest.mark.parametrize("options,pattern", [
    ({"morphology": "plain", "n_units": 1}, "n_units"),
    ({"morphology": "wavy"}, "morphology"),
    ({"colour": "red"}, "build option"),
    ({"morphology": "plain", "root_support": True}, "root_support applies to the spanwise"),
    ({"morphology": "spanwise", "root_support": "yes"}, "root_support = 'yes' must be true or false"),
    ({"drag_points": 0}, "drag_points = 0 must be an integer in \\[1, 64\\]"),
    ({"drag_points": 2.5}, "drag_points = 2.5"),
    ({"drag_split": 1}, "drag_split = 1 must be true or false"),
])
def test_bad_build_options_are_refused(options, pattern):
    with pytest.raises(ModelError, match=pattern):
        build_model("feather", options)


def test_unknown_parameter_is_named():
    with pytest.raises(ModelError, match="width_ratio"):
        build_model("feather", {"morphology": "plain"}).parameter_vector({"width_ratio": 7.5})
