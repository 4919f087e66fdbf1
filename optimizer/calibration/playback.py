"""A scene block that replays a recorded root angle: the feather moves exactly as it did on the bench.

Calibration drives the simulated feather with the servo's recorded read-back, not with the
commanded stroke through a servo model, so the fitted coefficients are the feather's and not a
mix of feather and servo errors. The feather needs the root's rate and acceleration too (the
added-mass force is proportional to the acceleration); differentiating a quantised, sampled
angle twice would amplify its noise by 1/dt², so the angle is fitted by a quintic smoothing
spline (continuous acceleration) whose residual matches the read-back's noise, estimated from
the recording itself (`angle_noise_rad`: the robust spread of third differences, which a smooth
motion sampled at a few ms hardly has). A fixed smoothing is wrong both ways: too loose and the
servo's sharp starts and stops are rounded off (a 2 mrad residual misses the rate by 0.2 rad/s
and the acceleration by 20 rad/s² over a 1 s stroke), too tight and the noise is differentiated.

A recording starts with the feather at rest (the load cell was tared at t = 0), so the spline
is fitted with the root held still before the first sample: otherwise the free end of the
spline invents a rate and acceleration at t = 0.
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np
from scipy.interpolate import UnivariateSpline

from ...cosim.framework.block import Port, TimeSource
from ..errors import OptimizerError

# The least noise assumed: a 0.001° read-back register, or an angle simulated to a tolerance.
MIN_ANGLE_NOISE_RAD = 1e-5
REST_PADDING_S = 0.1     # root held still this long before a recording (it starts at rest)


def angle_noise_rad(angle_rad: np.ndarray) -> float:
    """The read-back's noise sd from the recording: MAD of third differences / sqrt(20) (white
    noise of sd s has third differences of sd s·sqrt(20)), at least MIN_ANGLE_NOISE_RAD."""
    third = np.diff(np.asarray(angle_rad, dtype=float), 3)
    if third.size == 0:
        return MIN_ANGLE_NOISE_RAD
    return max(float(np.median(np.abs(third))) / 0.6745 / np.sqrt(20.0), MIN_ANGLE_NOISE_RAD)


def angle_spline(time_s: np.ndarray, angle_rad: np.ndarray, noise_rad: float | None = None) -> UnivariateSpline:
    """The smoothing spline through a recorded angle that starts at rest (k = 5, residual ≈
    noise_rad per sample; default: estimated by `angle_noise_rad`)."""
    time_s, angle_rad = np.asarray(time_s, dtype=float), np.asarray(angle_rad, dtype=float)
    if len(time_s) < 8 or not np.all(np.diff(time_s) > 0):
        raise OptimizerError("a recorded angle needs at least 8 samples at increasing times")
    if noise_rad is None:
        noise_rad = angle_noise_rad(angle_rad)
    dt = float(np.median(np.diff(time_s)))
    n_rest = max(1, int(round(REST_PADDING_S / dt)))
    rest_s = time_s[0] - dt * np.arange(n_rest, 0, -1)
    t = np.concatenate([rest_s, time_s])
    a = np.concatenate([np.full(n_rest, angle_rad[0]), angle_rad])
    return UnivariateSpline(t, a, k=5, s=len(t) * noise_rad**2)


class RecordedRoot(TimeSource):
    """Memoryless block: outputs angle_rad, rate_rad_s, accel_rad_s2 of a recorded root angle,
    held at its first and last values outside the recording. `path`: an .npz with time_s and
    angle_rad (a scene's parameters are plain values, so the recording comes by file)."""

    def __init__(self, name: str, path: str) -> None:
        super().__init__()
        self.name = name
        try:
            with np.load(Path(path)) as data:
                time_s, angle_rad = data["time_s"], data["angle_rad"]
        except (OSError, KeyError, ValueError) as exc:
            raise OptimizerError(f"{name}: cannot read the recorded root angle from {path} ({exc})") from None
        self._spline = angle_spline(time_s, angle_rad)
        self._derivatives = (self._spline.derivative(1), self._spline.derivative(2))
        self._span = (float(time_s[0]), float(time_s[-1]))
        self.outputs = {
            "angle_rad": Port("angle_rad", "rad", "recorded root angle (smoothed)"),
            "rate_rad_s": Port("rate_rad_s", "rad/s", "its rate"),
            "accel_rad_s2": Port("accel_rad_s2", "rad/s2", "its acceleration"),
        }

    def evaluate(self, t_s: float, inputs: Mapping[str, float]) -> dict[str, float]:
        t = min(max(t_s, self._span[0]), self._span[1])
        if t != t_s:   # outside the recording: the root holds still
            return {"angle_rad": float(self._spline(t)), "rate_rad_s": 0.0, "accel_rad_s2": 0.0}
        return {"angle_rad": float(self._spline(t)), "rate_rad_s": float(self._derivatives[0](t)),
                "accel_rad_s2": float(self._derivatives[1](t))}
