"""Why a bench study settles under each new stroke instead of resting longer (bench/bench_loop_prior.py,
docs/bench-loop.md "A prior that learns the simulation's bias").

The FMU plant with the plate wake law (`feather.wake = plate`, the bench of the prior benchmark)
remembers the previous stroke: the wake's decay scales with the plate's normal speed, so at rest
it hardly decays, and a stroke's first periods depend on what ran before it. Running the new
stroke erases it. Offline (the plant advanced directly, no emulator, no real time): two
predecessors, two rests, the same stroke after each; per-period mean thrust compared.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from featherstar.hil.fmu_plant import FmuPlant
from featherstar.hil.plant import fmu_plant_form

pytestmark = pytest.mark.hil

HIDDEN = {"feather.wake": "plate", "feather.added_mass_scale": 1.5, "feather.wake_drag_coeff": 8.0,
          "feather.joint_damping_Nms_rad": 0.003}   # bench/bench_loop_prior.py's bench
STEP_S = 0.01
AMPLITUDE_RAD = 0.5


def _periods(plant: FmuPlant, periods: int, down_fraction: float) -> np.ndarray:
    """Mean thrust (N) of each 1 s period of a sinusoid whose first half-swing takes
    `down_fraction` of the period (an asymmetric stroke)."""
    n = round(1.0 / STEP_S)
    means = []
    for _ in range(periods):
        total = 0.0
        for j in range(n):
            phase = j / n
            x = (0.5 * phase / down_fraction if phase < down_fraction
                 else 0.5 + 0.5 * (phase - down_fraction) / (1 - down_fraction))
            plant.set_setpoint_rad(AMPLITUDE_RAD * math.sin(2 * math.pi * x))
            plant.advance(STEP_S)
            total += plant.thrust_N
        means.append(total / n)
    return np.array(means)


def _after(previous_down_fraction: float, rest_s: float, periods: int = 7) -> np.ndarray:
    form = fmu_plant_form(HIDDEN)
    plant = FmuPlant("plain", feather_parameters=form.feather, servo_parameters=form.servo,
                     feather_options=form.feather_options)
    try:
        _periods(plant, 3, previous_down_fraction)
        plant.set_setpoint_rad(0.0)
        for _ in range(round(rest_s / STEP_S)):
            plant.advance(STEP_S)
        return _periods(plant, periods, 0.35)
    finally:
        plant.close()


def test_rest_does_not_erase_the_plate_wake_s_memory_of_the_previous_stroke_settling_does():
    short = _after(0.25, 3.0) - _after(0.75, 3.0)
    long = _after(0.25, 10.0) - _after(0.75, 10.0)
    # Measured: 7.2 and 6.1 mN apart in the second period after 3 s and 10 s of rest, 0.7 in the seventh.
    assert abs(short[1]) > 3e-3
    assert abs(long[1]) > 0.5 * abs(short[1])             # 7 s more rest: most of the memory is left
    assert abs(short[6]) < 0.15 * abs(short[1])          # 5 periods of the new stroke: most is gone
    assert np.all(np.diff(np.abs(short[1:])) < 0)          # and it decays period by period
