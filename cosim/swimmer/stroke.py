"""The paper's 4-phase stroke: rise, hold up, fall, hold down, repeated with a fixed period.

The root angle goes from -A/2 to +A/2 over t_up (the upstroke), holds for t_hold_up, returns over
t_down (the downstroke) and holds for t_hold_down. Ramps follow the minimum-jerk profile
10τ³ − 15τ⁴ + 6τ⁵: angle, rate and acceleration are continuous, so the added-mass force (which is
proportional to the root acceleration) stays finite. A linear ramp has infinite acceleration at
its corners and would put infinite spikes into the measured thrust.

A stroke is given either by absolute times or, as in the paper's optimizer, by three base-10
log-ratios at a fixed period: log10(t_up/t_down), log10(t_hold_up/t_hold_down) and
log10(t_hold/t_move), with t_hold = t_hold_up + t_hold_down and t_move = t_up + t_down.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca

from ...fmu_src.errors import ModelError
# the stroke's CasADi expressions live beside its FMU model (the SSP export's stroke source)
from ...fmu_src.stroke_source import root_motion_symbolic

#: Peak rate of the minimum-jerk ramp is this factor times (amplitude / ramp time).
MIN_JERK_PEAK_RATE_FACTOR = 1.875


@dataclass(frozen=True)
class Stroke:
    """Times in seconds; amplitude_deg is peak to peak, centred on zero."""

    t_up_s: float = 0.25
    t_hold_up_s: float = 0.5
    t_down_s: float = 0.25
    t_hold_down_s: float = 0.5
    amplitude_deg: float = 60.0

    def __post_init__(self) -> None:
        for name in ("t_up_s", "t_down_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ModelError(f"stroke '{name}' = {value!r} s must be > 0")
        for name in ("t_hold_up_s", "t_hold_down_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ModelError(f"stroke '{name}' = {value!r} s must be >= 0")
        if not (0 < self.amplitude_deg <= 180):
            raise ModelError(f"stroke 'amplitude_deg' = {self.amplitude_deg!r} must be in (0, 180]")

    @property
    def period_s(self) -> float:
        return self.t_up_s + self.t_hold_up_s + self.t_down_s + self.t_hold_down_s

    @property
    def amplitude_rad(self) -> float:
        return math.radians(self.amplitude_deg)

    def log_ratios(self) -> tuple[float, float, float]:
        """(log10 t_up/t_down, log10 t_hold_up/t_hold_down, log10 t_hold/t_move); a zero hold gives -inf."""
        t_hold = self.t_hold_up_s + self.t_hold_down_s

        def log10(a: float, b: float) -> float:
            if a == 0:
                return -math.inf
            return math.inf if b == 0 else math.log10(a / b)

        return (
            math.log10(self.t_up_s / self.t_down_s),
            log10(self.t_hold_up_s, self.t_hold_down_s),
            log10(t_hold, self.t_up_s + self.t_down_s),
        )

    def peak_rate_rad_s(self) -> float:
        """Largest root angular speed the stroke asks for."""
        return MIN_JERK_PEAK_RATE_FACTOR * self.amplitude_rad / min(self.t_up_s, self.t_down_s)


def stroke_from_log_ratios(
    period_s: float,
    log10_up_down: float,
    log10_hold_up_down: float,
    log10_hold_move: float,
    amplitude_deg: float = 60.0,
) -> Stroke:
    """The stroke with the given base-10 log time ratios and period (the paper's optimizer variables)."""
    if not (math.isfinite(period_s) and period_s > 0):
        raise ModelError(f"stroke period_s = {period_s!r} s must be > 0")
    t_move = period_s / (1.0 + 10.0**log10_hold_move)
    t_hold = period_s - t_move
    up_fraction = 1.0 / (1.0 + 10.0**-log10_up_down)
    hold_up_fraction = 1.0 / (1.0 + 10.0**-log10_hold_up_down)
    return Stroke(
        t_up_s=t_move * up_fraction,
        t_hold_up_s=t_hold * hold_up_fraction,
        t_down_s=t_move * (1.0 - up_fraction),
        t_hold_down_s=t_hold * (1.0 - hold_up_fraction),
        amplitude_deg=amplitude_deg,
    )


def min_jerk(tau: float) -> tuple[float, float, float]:
    """Minimum-jerk blend s(τ) on [0, 1] and its first two derivatives in τ."""
    tau = min(max(tau, 0.0), 1.0)
    t2 = tau * tau
    return (
        t2 * tau * (10.0 - 15.0 * tau + 6.0 * t2),
        30.0 * t2 * (1.0 - 2.0 * tau + t2),
        60.0 * tau * (1.0 - 3.0 * tau + 2.0 * t2),
    )


def root_motion(stroke: Stroke, t_s: float) -> tuple[float, float, float]:
    """Root angle (rad), rate (rad/s) and acceleration (rad/s²) at time t_s."""
    amplitude = stroke.amplitude_rad
    phase = t_s % stroke.period_s
    if phase < stroke.t_up_s:
        ramp, duration, sign = phase / stroke.t_up_s, stroke.t_up_s, 1.0
    elif phase < stroke.t_up_s + stroke.t_hold_up_s:
        return 0.5 * amplitude, 0.0, 0.0
    elif phase < stroke.t_up_s + stroke.t_hold_up_s + stroke.t_down_s:
        ramp = (phase - stroke.t_up_s - stroke.t_hold_up_s) / stroke.t_down_s
        duration, sign = stroke.t_down_s, -1.0
    else:
        return -0.5 * amplitude, 0.0, 0.0
    s, ds, dds = min_jerk(ramp)
    return (
        sign * amplitude * (s - 0.5),
        sign * amplitude * ds / duration,
        sign * amplitude * dds / duration**2,
    )


def root_motion_function() -> ca.Function:
    """root_motion_symbolic as a Function (t_s, [t_up, t_hold_up, t_down, t_hold_down,
    amplitude_rad]) -> (angle_rad, rate_rad_s, accel_rad_s2): one function for every stroke."""
    t = ca.SX.sym("t_s")
    p = ca.SX.sym("stroke", 5)
    angle, rate, accel = root_motion_symbolic(t, p[0], p[1], p[2], p[3], p[4])
    return ca.Function("featherstar_root_motion", [t, p], [angle, rate, accel],
                       ["t_s", "stroke"], ["angle_rad", "rate_rad_s", "accel_rad_s2"])
