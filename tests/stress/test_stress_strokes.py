"""The fastest strokes the servo allows, amplitudes up to 120°, periods 0.3–6 s.

The MG996R servo turns at most ω0 = 6.2 rad/s; a minimum-jerk ramp over amplitude A peaks at
1.875·A/t_ramp, so the fastest ramp it can follow is t_ramp = 1.875·A/ω0 (0.11 s for 20°, 0.32 s
for 60°, 0.63 s for 120°). The kinematic scene prescribes such strokes exactly; the test bed is
also commanded strokes faster than that, which the servo must clip at its speed limit.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from featherstar.cosim.swimmer.stroke import MIN_JERK_PEAK_RATE_FACTOR
from featherstar.fmu_src.servo import servo_model
from stress_support import FLAP, assert_physical, plain_stroke_overrides, run_case

pytestmark = pytest.mark.stress

OMEGA0 = servo_model().default_parameters()["no_load_speed_rad_s"]
SETTLE_S = 4.5  # the plain feather's transient decays in time, not in periods (weak drag at small amplitude)


def run_length(period_s: float) -> dict[str, int]:
    periods = max(5, math.ceil(SETTLE_S / period_s) + 2)
    return {"master.periods": periods, "metrics.settle_periods": periods - 2}


def fastest_ramp_s(amplitude_deg: float) -> float:
    return MIN_JERK_PEAK_RATE_FACTOR * math.radians(amplitude_deg) / OMEGA0


@pytest.mark.parametrize("amplitude_deg,period_s", [
    (20.0, 0.3),    # the shortest period: only small amplitudes fit the servo's speed in 0.3 s
    (60.0, 0.75),
    (120.0, 1.5),   # the largest amplitude at the paper's period, ramps at the speed limit
    (60.0, 6.0),    # the longest period: long holds between fast ramps
])
def test_plain_feather_under_the_fastest_servo_strokes(amplitude_deg, period_s):
    stroke = plain_stroke_overrides(amplitude_deg, period_s, fastest_ramp_s(amplitude_deg))
    result = run_case("kinematic", {"feather.morphology": "plain", **stroke, **run_length(period_s)})
    metrics = assert_physical(result, "kinematic", "plain")
    peak_rate = float(np.max(np.abs(result["controller.rate_rad_s"])))
    assert peak_rate == pytest.approx(OMEGA0, rel=1e-2)  # the stroke really is at the servo's limit
    # symmetric stroke, plain feather: TR near 1 (buoyancy breaks the symmetry most at small amplitude:
    # 0.90 at 20°, 0.99 at 60°)
    assert 0.8 < metrics["thrust_ratio"] < 1.25


def test_spanwise_flap_at_120_degrees_stays_within_its_fold_limit():
    stroke = plain_stroke_overrides(120.0, 1.5, fastest_ramp_s(120.0))
    result = run_case("kinematic", {"feather.morphology": "spanwise", **stroke, "master.periods": 4,
                                    "metrics.settle_periods": 2})
    assert_physical(result, "kinematic", "spanwise")
    fold = result[FLAP]
    assert np.max(fold) < math.radians(160.0) + math.radians(2.0)  # the second stop holds
    assert np.max(fold) > math.radians(20.0)  # and the flap does fold


@pytest.mark.parametrize("morphology", ["plain", "spanwise"])
def test_servo_clips_strokes_faster_than_it_can_turn(morphology):
    """120° commanded in 0.1 s ramps (3x too fast): the servo follows at its speed limit, which
    also falls with the feather's load torque."""
    stroke = plain_stroke_overrides(120.0, 1.5, 0.1)
    result = run_case("testbed", {"feather.morphology": morphology, **stroke, "master.periods": 4,
                                  "metrics.settle_periods": 2})
    assert_physical(result, "testbed", morphology)
    rate = result["servo.rate_rad_s"]
    assert np.max(np.abs(rate)) <= OMEGA0 * 1.001
    assert np.max(np.abs(rate)) > 0.8 * OMEGA0  # it does run at (close to) full speed
