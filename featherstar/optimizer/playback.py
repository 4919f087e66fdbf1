"""A scene block that replays a recorded root angle: the feather moves exactly as it did on the bench.

Calibration drives the simulated feather with the servo's recorded read-back, not with the
commanded stroke through a servo model, so the fitted coefficients are the feather's and not a
mix of feather and servo errors. The feather needs the root's rate and acceleration too (the
added-mass force is proportional to the acceleration); differentiating a quantised, sampled
angle twice would amplify its noise by 1/dt², so the angle is fitted by a quintic smoothing
spline (continuous acceleration) whose residual matches the read-back's noise,
`ANGLE_NOISE_RAD` (a 0.01° register, sampled with ~1 ms of timing jitter at ~5 rad/s).
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np
from scipy.interpolate import UnivariateSpline

from ..cosim.block import Port

from .errors import OptimizerError

ANGLE_NOISE_RAD = 2e-3


def angle_spline(time_s: np.ndarray, angle_rad: np.ndarray, noise_rad: float = ANGLE_NOISE_RAD) -> UnivariateSpline:
    """The smoothing spline through a recorded angle (k = 5, residual ≈ noise_rad per sample)."""
    time_s, angle_rad = np.asarray(time_s, dtype=float), np.asarray(angle_rad, dtype=float)
    if len(time_s) < 8 or not np.all(np.diff(time_s) > 0):
        raise OptimizerError("a recorded angle needs at least 8 samples at increasing times")
    return UnivariateSpline(time_s, angle_rad, k=5, s=len(time_s) * noise_rad**2)


class RecordedRoot:
    """Memoryless block: outputs angle_rad, rate_rad_s, accel_rad_s2 of a recorded root angle,
    held at its first and last values outside the recording. `path`: an .npz with time_s and
    angle_rad (a scene's parameters are plain values, so the recording comes by file)."""

    can_iterate = True

    def __init__(self, name: str, path: str) -> None:
        self.name = name
        try:
            with np.load(Path(path)) as data:
                time_s, angle_rad = data["time_s"], data["angle_rad"]
        except (OSError, KeyError, ValueError) as exc:
            raise OptimizerError(f"{name}: cannot read the recorded root angle from {path} ({exc})") from None
        self._spline = angle_spline(time_s, angle_rad)
        self._derivatives = (self._spline.derivative(1), self._spline.derivative(2))
        self._span = (float(time_s[0]), float(time_s[-1]))
        self.inputs: dict[str, Port] = {}
        self.outputs = {
            "angle_rad": Port("angle_rad", "rad", "recorded root angle (smoothed)"),
            "rate_rad_s": Port("rate_rad_s", "rad/s", "its rate"),
            "accel_rad_s2": Port("accel_rad_s2", "rad/s2", "its acceleration"),
        }
        self._t = 0.0

    def evaluate(self, t_s: float, inputs: Mapping[str, float]) -> dict[str, float]:
        t = min(max(t_s, self._span[0]), self._span[1])
        if t != t_s:   # outside the recording: the root holds still
            return {"angle_rad": float(self._spline(t)), "rate_rad_s": 0.0, "accel_rad_s2": 0.0}
        return {"angle_rad": float(self._spline(t)), "rate_rad_s": float(self._derivatives[0](t)),
                "accel_rad_s2": float(self._derivatives[1](t))}

    def start(self, t0_s: float) -> None:
        self._t = t0_s

    def set_inputs(self, values: Mapping[str, float]) -> None:
        pass

    def get_outputs(self) -> dict[str, float]:
        return self.evaluate(self._t, {})

    def do_step(self, t_s: float, h_s: float) -> None:
        self._t = t_s + h_s

    def close(self) -> None:
        pass
