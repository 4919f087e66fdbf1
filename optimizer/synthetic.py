"""An analytic stand-in for the FMU master: a feather whose thrust follows quasi-steady drag.

For tests, benchmarks of the optimizer's own overhead, and demos without compiled models. It
honours the same overrides as the master (controller times, amplitude, morphology) and returns a
thrust series at 1 kHz, so noise and metrics go through exactly the path real runs take.

Model: during a ramp the thrust is ∓ c·S·ω(t)² (drag on the feather, ω the root rate of the
minimum-jerk ramp), positive on the downstroke. Flaps change the area S per stroke:

* upstroke: flaps fold with the flow, more so when the stroke is fast (fold time τ_fold), leaving
  S_up = 1 − f·exp(−t_up/τ_fold) of the full area;
* downstroke: flaps only lie flat if they had time to unfold during the hold after the upstroke
  (time constant τ_unfold): S_down = 1 − f·exp(−t_hold_up/τ_unfold).

f is the folding area fraction: 0 for the plain feather (TR = t_up/t_down, the rigid-plate drag
result), and for flapped feathers a bump over the width or length ratio, peaking at WR 7.5 and
LR 2 as in the paper's simulations.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .errors import OptimizerError
from .objective import Overrides, Trace
from .sweep import W_SPINE_M

_WIDTH_RATIO_PEAK = 7.5
_LENGTH_RATIO_PEAK = 2.0
_REFERENCE_AREA_M2 = 0.075 * 0.115
MORPHOLOGIES = ("plain", "chordwise", "spanwise")


@dataclass(frozen=True)
class SyntheticFeather:
    """Defaults describe the paper's feathers (w 75 mm, l 115 mm, flap fraction up to 0.8)."""

    morphology: str = "chordwise"
    max_flap_fraction: float = 0.8
    fold_time_s: float = 1.0
    unfold_time_s: float = 0.3
    drag_coefficient_N_s2: float = 0.02
    sample_rate_hz: float = 1000.0

    def __post_init__(self) -> None:
        if self.morphology not in MORPHOLOGIES:
            raise OptimizerError(f"unknown synthetic morphology {self.morphology!r}; known: {list(MORPHOLOGIES)}")

    def flap_fraction(self, overrides: Overrides) -> float:
        morphology = str(overrides.get("feather.morphology", self.morphology))
        if morphology == "plain":
            return 0.0
        if morphology == "chordwise":
            ratio = float(overrides.get("feather.width_ratio", _WIDTH_RATIO_PEAK))
            return self.max_flap_fraction * math.exp(-(((ratio - _WIDTH_RATIO_PEAK) / 4.0) ** 2))
        if morphology == "spanwise":
            ratio = float(overrides.get("feather.length_ratio", _LENGTH_RATIO_PEAK))
            return 0.7 * self.max_flap_fraction * math.exp(-(((ratio - _LENGTH_RATIO_PEAK) / 0.8) ** 2))
        raise OptimizerError(f"unknown feather.morphology {morphology!r}; known: {list(MORPHOLOGIES)}")

    def check(self, overrides: Overrides, duration_s: float) -> None:
        """What a master's plan would refuse: an unknown morphology."""
        self.flap_fraction(overrides)

    def __call__(self, overrides: Overrides, duration_s: float) -> Trace:
        started = time.perf_counter()
        t_up = float(overrides.get("controller.t_up_s", 0.25))
        t_hold_up = float(overrides.get("controller.t_hold_up_s", 0.5))
        t_down = float(overrides.get("controller.t_down_s", 0.25))
        t_hold_down = float(overrides.get("controller.t_hold_down_s", 0.5))
        amplitude_rad = math.radians(float(overrides.get("controller.amplitude_deg", 60.0)))
        if str(overrides.get("feather.morphology", self.morphology)) == "chordwise":
            width_m = W_SPINE_M * float(overrides.get("feather.width_ratio", _WIDTH_RATIO_PEAK))
        else:
            width_m = float(overrides.get("feather.width_m", 0.075))
        area = width_m * float(overrides.get("feather.length_m", 0.115)) / _REFERENCE_AREA_M2
        flaps = self.flap_fraction(overrides)
        area_up = area * (1.0 - flaps * math.exp(-t_up / self.fold_time_s))
        area_down = area * (1.0 - flaps * math.exp(-t_hold_up / self.unfold_time_s))

        time_s = np.arange(0.0, duration_s + 2.0 / self.sample_rate_hz, 1.0 / self.sample_rate_hz)
        phase = np.mod(time_s, t_up + t_hold_up + t_down + t_hold_down)
        down_start = t_up + t_hold_up
        rising = phase < t_up
        falling = (phase >= down_start) & (phase < down_start + t_down)
        tau = np.where(rising, phase / t_up, (phase - down_start) / t_down).clip(0.0, 1.0)
        rate = 30.0 * tau**2 * (1.0 - tau) ** 2 * amplitude_rad / np.where(rising, t_up, t_down)
        thrust = self.drag_coefficient_N_s2 * rate**2 * np.where(rising, -area_up, area_down)
        thrust = np.where(rising | falling, thrust, 0.0)
        return Trace(time_s, thrust, time.perf_counter() - started)

    def true_thrust_ratio(self, overrides: Overrides) -> float:
        """Noise-free TR over whole periods: ratio of the two stroke impulses."""
        t_up = float(overrides.get("controller.t_up_s", 0.25))
        t_down = float(overrides.get("controller.t_down_s", 0.25))
        t_hold_up = float(overrides.get("controller.t_hold_up_s", 0.5))
        flaps = self.flap_fraction(overrides)
        down = (1.0 - flaps * math.exp(-t_hold_up / self.unfold_time_s)) / t_down
        up = (1.0 - flaps * math.exp(-t_up / self.fold_time_s)) / t_up
        return down / up
