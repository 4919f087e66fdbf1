"""The emulator's FMU plant is the converged model: servo and feather strongly coupled.

The emulator receives setpoints at the client's step and holds each one (a zero-order hold, as
a servo controller does), so the plant's only discretisation is that hold: as the setpoint step
shrinks, its thrust must converge, at first order, to the strong simulation of the continuous
stroke (the testbed scene). The Gauss–Seidel plant this replaces converged to the macro step's
error instead (22.8 mN at 1 ms for this stroke, against 10.6 mN converged: docs/hil.md).
"""
from __future__ import annotations

import numpy as np
import pytest
from featherstar.cosim.scenes import load_scene
from featherstar.cosim.swimmer.controller import resolve_stroke
from featherstar.cosim.swimmer.metrics import thrust_metrics
from featherstar.cosim.swimmer.run import run_scene
from featherstar.cosim.swimmer.stroke import root_motion
from featherstar.hil.fmu_plant import FmuPlant

pytestmark = pytest.mark.hil

# An asymmetric stroke (fast downstroke): its mean thrust is a small difference of large
# impulses, the most sensitive check of the coupling.
STROKE = {"log10_up_down": 0.35, "log10_hold_up_down": 0.0, "log10_hold_move": -0.3, "period_s": 1.0}
PERIODS, SETTLE = 4, 1


def _stroke():
    table = load_scene("testbed").to_dict()["blocks"]["controller"]
    settings = {k: v for k, v in table.items() if k == "amplitude_deg"}
    return resolve_stroke(settings, STROKE, "test stroke")


def _plant_mean_thrust_N(setpoint_step_s: float, chunks: int = 1, wake: str = "none") -> tuple[float, np.ndarray]:
    """Mean thrust over the measured periods with the stroke written every setpoint_step_s (held
    in between), the plant advanced in `chunks` unequal pieces per step (as requests arrive)."""
    stroke, plant = _stroke(), FmuPlant("plain", feather_options={"wake": wake})
    n = round(PERIODS * stroke.period_s / setpoint_step_s)
    pieces = np.arange(1, chunks + 1, dtype=float)
    pieces = pieces / pieces.sum() * setpoint_step_s
    t, thrust = [0.0], [0.0]
    try:
        for k in range(n):
            plant.set_setpoint_rad(root_motion(stroke, k * setpoint_step_s)[0])
            for piece in pieces:
                plant.advance(piece)
            t.append(plant.t_s)
            thrust.append(plant.thrust_N)
    finally:
        plant.close()
    t_s, thrust_N = np.array(t), np.array(thrust)
    window = (SETTLE * stroke.period_s, PERIODS * stroke.period_s)
    return thrust_metrics(t_s, thrust_N, *window, None, 0)["mean_thrust_N"], thrust_N


def test_plant_converges_to_the_strong_simulation_of_the_stroke():
    strong_N = run_scene("testbed", {"feather.morphology": "plain", **{f"controller.{k}": v for k, v in STROKE.items()},
                                     "master.periods": PERIODS, "metrics.settle_periods": SETTLE}).summary["mean_thrust_N"]
    coarse_N, _ = _plant_mean_thrust_N(4e-3)
    fine_N, _ = _plant_mean_thrust_N(1e-3)
    coarse_error, fine_error = abs(coarse_N - strong_N), abs(fine_N - strong_N)
    assert fine_error < 0.02 * abs(strong_N)
    # First order in the hold (the setpoint's mean delay is half a step): 4x the step, ~4x the error.
    assert 2.5 < coarse_error / fine_error < 6.0, (coarse_N, fine_N, strong_N)


def test_plant_state_does_not_depend_on_how_requests_chop_up_time():
    one, thrust_one = _plant_mean_thrust_N(4e-3, chunks=1)
    three, thrust_three = _plant_mean_thrust_N(4e-3, chunks=3)
    assert three == pytest.approx(one, rel=1e-4)
    assert np.max(np.abs(thrust_three - thrust_one)) < 1e-4 * np.max(np.abs(thrust_one))


def test_a_plant_with_a_wake_law_is_that_model_not_the_quasi_steady_one():
    # The plant's model form is the feather's build option: with the plate's wake the same stroke
    # gives another thrust, and the one the strong simulation of the same model gives.
    strong_N = run_scene("testbed", {"feather.morphology": "plain", "feather.wake": "plate",
                                     **{f"controller.{k}": v for k, v in STROKE.items()},
                                     "master.periods": PERIODS, "metrics.settle_periods": SETTLE}).summary["mean_thrust_N"]
    plate_N, _ = _plant_mean_thrust_N(1e-3, wake="plate")
    none_N, _ = _plant_mean_thrust_N(1e-3)
    assert abs(plate_N - strong_N) < 0.02 * abs(strong_N)
    assert abs(plate_N - none_N) > 0.1 * abs(none_N), (plate_N, none_N)
