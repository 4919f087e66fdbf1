"""The feather's wake option (issue 26, item 1) against physics: the reactive force still has zero
mean, the energy balance closes with the wake's energy and dissipation, a wake that is never set
moving is the quasi-steady model with the constant C_0, a strip in a steady stream settles to the
law's analytic state, and a rigid plate's wake thrust agrees with bench/wake_memory.py's
independent strip model."""
import importlib.util
import json
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from test_fluid_physics import OUT, STROKES, drive, window_means

from featherstar.cosim.swimmer.stroke import Stroke
from featherstar.fmu_src.errors import ModelError
from featherstar.fmu_src.feather import feather_model
from featherstar.fmu_src.fluid import WAKE_CONSTANTS, WAKE_LAWS
from featherstar.fmu_src.integrate import integrate
from featherstar.fmu_src.model import Model, Variable

WAKE_OUT = {"wake_energy": 9, "dissipation": 10}
BENCH = Path(__file__).resolve().parents[2] / "bench" / "wake_memory.py"


@pytest.mark.parametrize("law,morphology,n_units,stroke_name", [
    ("relative", "plain", 4, "optimizer-found"), ("self", "chordwise", 3, "symmetric"), ("plate", "spanwise", 4, "random-0")])
def test_reactive_force_has_zero_mean_with_a_wake(law, morphology, n_units, stroke_name):
    mean_thrust, mean_drag, momentum_change, spread = window_means(
        feather_model(morphology, n_units, wake=law), STROKES[stroke_name])
    assert mean_thrust - mean_drag == pytest.approx(momentum_change, abs=1e-6 * (abs(mean_drag) + 1e-3))
    assert abs(mean_thrust - mean_drag) <= max(spread, 1e-4 * abs(mean_drag), 1e-7)


def with_power_integrals(model: Model) -> Model:
    """Two more states: the actuator's work ∫ τ θ̇0 dt and the water's dissipation ∫ P_d dt."""
    work = ca.SX.sym("work", 2)
    return Model(
        name=model.name, description=model.description, parameters=model.parameters, outputs=model.outputs,
        states=(*model.states, Variable("work_J", "J", ""), Variable("dissipated_J", "J", "")),
        inputs=model.inputs, x=ca.vertcat(model.x, work), u=model.u, p=model.p,
        xdot=ca.vertcat(model.xdot, model.y[OUT["torque"]] * model.u[1], model.y[WAKE_OUT["dissipation"]]), y=model.y,
    )


@pytest.mark.parametrize("morphology,law", [("plain", law) for law in WAKE_LAWS] + [("chordwise", "relative")])
def test_energy_balance_closes_with_the_wake(morphology, law):
    """Sheet and stops undamped: the actuator's work = Δ(mechanical + wake energy) + what the
    water dissipates (relative motion and the wake's decay), to 1e-6 of the work."""
    model = with_power_integrals(feather_model(morphology, 3, wake=law))
    undamped = {"retardation_time_s": 0.0}
    if morphology == "chordwise":
        undamped["contact_damping_Nms_rad_m"] = 0.0
    stroke = STROKES["optimizer-found"]
    grid = np.linspace(0, 2 * stroke.period_s, 7)
    states, y = integrate(model, grid, drive(stroke), undamped, rtol=1e-10, atol=1e-12)
    work, dissipated = states[:, -2], states[:, -1]
    stored = y[:, OUT["energy"]] + y[:, WAKE_OUT["wake_energy"]]
    assert work[-1] > 0 and dissipated[-1] > 0 and np.max(y[:, WAKE_OUT["wake_energy"]]) > 0
    np.testing.assert_allclose(stored - stored[0] + dissipated, work, atol=1e-6 * work[-1])


@pytest.mark.parametrize("law", WAKE_LAWS)
def test_a_wake_never_set_moving_is_the_quasi_steady_model_with_c0(law):
    """B = 0: u stays 0, and every derivative and output equals the quasi-steady model's with the
    constant C_d = C_0, at random states."""
    quasi = feather_model("chordwise", 3)
    waked = feather_model("chordwise", 3, wake=law)
    rng = np.random.default_rng(3)
    n = quasi.x.numel()
    c0 = WAKE_CONSTANTS[law][0]
    for _ in range(5):
        x = rng.normal(0, 0.5, n)
        u = rng.normal(0, [1, 5, 50, 0.1])
        a = [np.array(v).ravel() for v in quasi.function()(x, u, quasi.parameter_vector({"oscillatory_drag": 0, "drag_coeff": c0}))]
        b = [np.array(v).ravel() for v in waked.function()(np.r_[x, np.zeros(waked.x.numel() - n)], u,
                                                          waked.parameter_vector({"wake_forcing": 0.0}))]
        np.testing.assert_allclose(b[0][:n], a[0], rtol=1e-12, atol=1e-12 * np.max(np.abs(a[0])))
        assert np.all(b[0][n:] == 0)
        np.testing.assert_allclose(b[1][:9], a[1], rtol=1e-12, atol=1e-12 * np.max(np.abs(a[1])))


def test_strip_in_a_steady_stream_settles_to_the_analytic_wake():
    """Root held broadside in a stream U ('relative' law): B s² = u s/γ, so the drag settles to
    ½ρ C_0 A U² / (1 + Bγ)², the steady-plate end of the law's fit."""
    model = feather_model("plain", 2, wake="relative")
    stiff = {"youngs_modulus_Pa": 1e11, "thickness_m": 3e-3, "gravity_m_s2": 0.0}
    speed = 0.05
    grid = np.array([0.0, 60.0, 80.0])
    states, y = integrate(model, grid, lambda t: ca.vertcat(0.0, 0.0, 0.0, speed), stiff, rtol=1e-9, atol=1e-12)
    c0, forcing, gamma = WAKE_CONSTANTS["relative"]
    values = model.default_parameters()
    expected = 0.5 * 1000.0 * c0 * values["width_m"] * values["length_m"] * speed**2 / (1 + forcing * gamma) ** 2
    # The stream moves at −U relative to the root: it pushes the feather along −y.
    assert -y[-1, OUT["drag_thrust"]] == pytest.approx(expected, rel=2e-3)
    assert y[-1, OUT["drag_thrust"]] == pytest.approx(y[-2, OUT["drag_thrust"]], rel=1e-3)


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_wake_memory_model", BENCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)


@pytest.mark.parametrize("law", ["relative"])  # one law: each costs ~20 s, and the code path is shared
def test_rigid_plate_wake_thrust_ratio_matches_the_strip_study(bench, law):
    """A rigid, drag-only plate under a slow-return stroke: the feather model's TR with a wake
    equals that of bench/wake_memory.py's 16-strip plate (its own wake ODE, scipy) within 1 %,
    and is far below the quasi-steady t_up/t_down."""
    stroke = Stroke(0.9, 0.02, 0.32, 0.26)
    # Drag depends on the plate's kinematics alone: its mass may stay, and the sheet's damping keeps
    # the stiff joints' modes from setting CVODES' step.
    rigid = {"youngs_modulus_Pa": 1e10, "thickness_m": 5e-3, "added_mass_scale": 0.0, "gravity_m_s2": 0.0}
    periods = 3
    grid = np.linspace(0, periods * stroke.period_s, periods * 600 + 1)
    _, y = integrate(feather_model("plain", 4, wake=law), grid, drive(stroke), rigid, rtol=1e-8, atol=1e-11)
    thrust = y[-601:-1, OUT["drag_thrust"]]
    model_ratio = thrust[thrust > 0].sum() / -thrust[thrust < 0].sum()
    c0, forcing, gamma = WAKE_CONSTANTS[law]
    _, reference = bench.RigidPlate().thrust_N(stroke, bench.WakeModel(law, c0, forcing, gamma), periods=periods,
                                               samples=1201)
    t = np.linspace(0, 1, 1201)  # the bench's thrust includes the reactive part: remove it
    theta, rate, accel = np.array([bench.root_motion(stroke, (periods - 1 + x) * stroke.period_s) for x in t]).T
    drag_only = reference - bench.RigidPlate().reactive_thrust_N(theta, rate, accel)
    assert model_ratio == pytest.approx(bench.thrust_ratio(drag_only), rel=0.01)
    assert model_ratio < 0.8 * stroke.t_up_s / stroke.t_down_s


def test_wake_constants_are_the_fit_of_bench_wake_memory():
    fit = json.loads((BENCH.parents[1] / "docs" / "results" / "wake_memory.json").read_text())["laws"]
    for law, (drag_coeff_0, forcing, decay_widths) in WAKE_CONSTANTS.items():
        assert drag_coeff_0 == pytest.approx(fit[law]["drag_coeff_0"], rel=1e-4)
        assert forcing == pytest.approx(fit[law]["forcing_B"], rel=1e-4)
        assert decay_widths == pytest.approx(fit[law]["gamma_widths"], rel=1e-4)
        assert "steady_drag_coeff" in fit[law]


def test_unknown_wake_law_is_refused():
    with pytest.raises(ModelError, match="wake = 'memory' is unknown; valid: none, relative, self, plate"):
        feather_model("plain", 2, wake="memory")
