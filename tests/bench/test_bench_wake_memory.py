"""The wake-memory mechanism study (bench/wake_memory.py) rests on pieces with analytic answers:
the Fourier average, the wake's steady state, the rigid plate's reactive force and its symmetry."""
from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "wake_memory.py"


@pytest.fixture(scope="module")
def wm():
    spec = importlib.util.spec_from_file_location("bench_wake_memory", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses resolve their annotations through it
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)


@pytest.mark.parametrize("kc", [2.0, 10.0, 100.0])
def test_without_a_wake_the_fourier_average_returns_the_drag_coefficient(wm, kc):
    still = wm.WakeModel("relative", drag_coeff_0=1.7, forcing_B=0.0, gamma_widths=1.0)
    assert wm.sinusoidal_drag_coeff(still, kc) == pytest.approx(1.7, rel=1e-4)


def test_relative_decay_steady_state_is_analytic(wm):
    """Constant plate speed v: B s² = u s / γ, so u = Bγ s and s = v / (1 + Bγ)."""
    model = wm.WakeModel("relative", drag_coeff_0=7.0, forcing_B=0.4, gamma_widths=2.0)
    u = np.array([0.0])
    for _ in range(5_000):  # explicit Euler: its fixed point is the ODE's, whatever the step
        u = u + 1e-2 * model.rate(u, 1.0 - u, np.array(1.0), 1.0)
    assert u[0] == pytest.approx(0.8 / 1.8, rel=1e-6)
    # Far from reversals the strip then feels C_0 / (1 + Bγ)²: the high-KC end of the fit.
    assert wm.sinusoidal_drag_coeff(model, 2000.0, periods=3) == pytest.approx(7.0 / 1.8**2, rel=0.03)


def test_reactive_thrust_averages_to_zero_over_a_period(wm):
    plate = wm.RigidPlate()
    stroke = wm.Stroke(0.6, 0.1, 0.32, 0.48)
    t = np.linspace(0, stroke.period_s, 20001)
    theta, rate, accel = np.array([wm.root_motion(stroke, x) for x in t]).T
    reactive = plate.reactive_thrust_N(theta, rate, accel)
    assert abs(np.trapezoid(reactive, t)) < 1e-6 * np.trapezoid(np.abs(reactive), t)


def test_rigid_plate_drag_only_thrust_ratio_is_the_time_ratio_without_a_wake(wm):
    plate = wm.RigidPlate()
    stroke = wm.Stroke(0.7, 0.2, 0.35, 0.25)
    t = np.linspace(0, stroke.period_s, 30001)
    theta, rate, _ = np.array([wm.root_motion(stroke, x) for x in t]).T
    drag = plate.drag_thrust_N(theta, np.outer(rate, plate.radius_m), 2.0)
    assert wm.thrust_ratio(drag) == pytest.approx(0.7 / 0.35, rel=1e-3)


@pytest.mark.parametrize("law", ["relative", "self", "plate"])
def test_symmetric_stroke_gives_unit_thrust_ratio_with_a_wake(wm, law):
    """Up and down mirror each other (θ → −θ, cos θ even): whatever the wake law, TR = 1."""
    model = wm.WakeModel(law, drag_coeff_0=7.0, forcing_B=0.35, gamma_widths=2.5)
    _, thrust = wm.RigidPlate(strips=6).thrust_N(wm.Stroke(0.25, 0.5, 0.25, 0.5), model, periods=4, samples=3001)
    assert wm.thrust_ratio(thrust) == pytest.approx(1.0, abs=2e-3)
    assert math.isfinite(thrust.sum())


def test_a_wake_lowers_the_rigid_plate_thrust_ratio_under_an_asymmetric_stroke(wm):
    """The mechanism itself: a wake fed by a fast downstroke pushes back in the hold and the
    upstroke; with B = 0 the same plate keeps the quasi-steady gain."""
    plate = wm.RigidPlate(strips=6)
    stroke = wm.Stroke(1.1, 0.02, 0.32, 0.06)
    no_wake = wm.WakeModel("self", drag_coeff_0=2.0, forcing_B=0.0, gamma_widths=2.0)
    wake = wm.WakeModel("self", drag_coeff_0=7.0, forcing_B=0.33, gamma_widths=2.0)
    _, plain = plate.thrust_N(stroke, no_wake, periods=4, samples=3001)
    _, with_wake = plate.thrust_N(stroke, wake, periods=4, samples=3001)
    assert wm.thrust_ratio(with_wake) < wm.thrust_ratio(plain) - 0.5
