"""What the bench's load cell makes of a simulated thrust series, and the paper's metrics on it.

The optimizer must see the objective the way the paper's optimizer did: through a 0–3 kg load
cell, sampled, with measurement noise. A `LoadCell` averages the simulated thrust over each sample
interval (a sigma-delta ADC such as the HX711 integrates over its conversion time) and adds
Gaussian noise. The metrics are then taken on those samples over whole periods after settling:

* thrust ratio (paper Eq. 3): TR = ∫T⁺dt / ∫|T⁻|dt of the samples, integrated by the master's own
  `featherstar.cosim.swimmer.metrics.signed_integrals` (piecewise linear, split at zero crossings);
* mean thrust (paper Eq. 2): the mean of the samples, (1/n) Σ T_t.

Default noise: 0.02 % of the 29.4 N full scale, 5.9 mN standard deviation. That is the combined
error of a class-C3 cell and about what an HX711 reads on a 3 kg bar cell at its fast rate; it is
a quarter of the ≈ 25 mN mean thrust of a flapped feather, so single evaluations are visibly noisy,
like the paper's. Zero is allowed (an ideal sensor).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..cosim.swimmer.metrics import signed_integrals
from .errors import OptimizerError

GRAVITY_M_S2 = 9.80665
FULL_SCALE_N = 3.0 * GRAVITY_M_S2
DEFAULT_NOISE_SD_N = 2e-4 * FULL_SCALE_N


@dataclass(frozen=True)
class LoadCell:
    """A sampled, noisy force sensor. sample_rate_hz 80: the HX711's fast rate."""

    noise_sd_N: float = DEFAULT_NOISE_SD_N
    sample_rate_hz: float = 80.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.noise_sd_N) and self.noise_sd_N >= 0):
            raise OptimizerError(f"load-cell noise_sd_N = {self.noise_sd_N!r} must be >= 0")
        if not (math.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0):
            raise OptimizerError(f"load-cell sample_rate_hz = {self.sample_rate_hz!r} must be > 0")

    def read(
        self, time_s: np.ndarray, thrust_N: np.ndarray, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]:
        """(sample start times, noisy samples): thrust averaged over each sample interval plus noise."""
        time_s = np.asarray(time_s, dtype=float)
        thrust_N = np.asarray(thrust_N, dtype=float)
        if time_s.ndim != 1 or time_s.shape != thrust_N.shape or len(time_s) < 2:
            raise OptimizerError(
                f"thrust series must be two equal 1-D arrays of >= 2 samples, got time {time_s.shape} "
                f"and thrust {thrust_N.shape}"
            )
        if not np.all(np.diff(time_s) > 0):
            raise OptimizerError("thrust series time must increase strictly")
        if not np.all(np.isfinite(thrust_N)):
            raise OptimizerError("thrust series holds NaN or inf: the simulation diverged")
        impulse = np.concatenate(([0.0], np.cumsum(0.5 * (thrust_N[1:] + thrust_N[:-1]) * np.diff(time_s))))
        dt = 1.0 / self.sample_rate_hz
        edges = time_s[0] + dt * np.arange(int((time_s[-1] - time_s[0]) / dt + 1e-9) + 1)
        samples = np.diff(np.interp(edges, time_s, impulse)) / dt
        if self.noise_sd_N > 0:
            samples = samples + rng.normal(0.0, self.noise_sd_N, samples.shape)
        return edges[:-1], samples


@dataclass(frozen=True)
class Measurement:
    thrust_ratio: float
    mean_thrust_N: float


def measure(
    time_s: np.ndarray,
    thrust_N: np.ndarray,
    period_s: float,
    load_cell: LoadCell,
    rng: np.random.Generator,
    *,
    settle_periods: int = 3,
    periods: int = 5,
    windows: int = 1,
) -> list[Measurement]:
    """Metrics on `windows` consecutive windows of `periods` whole periods after `settle_periods`.

    Windows share one noisy reading, so their spread is the bench's repeat-to-repeat spread:
    sensor noise plus cycle-to-cycle variation of the (possibly chaotic) flapping.
    """
    needed_s = (settle_periods + windows * periods) * period_s
    span_s = float(time_s[-1] - time_s[0])
    if span_s < needed_s * (1 - 1e-9):
        raise OptimizerError(
            f"the run covers {span_s:.3f} s but {settle_periods} settling + {windows}×{periods} "
            f"measured periods of {period_s:.3f} s need {needed_s:.3f} s"
        )
    starts, samples = load_cell.read(time_s, thrust_N, rng)
    dt = 1.0 / load_cell.sample_rate_hz
    results = []
    for w in range(windows):
        begin = time_s[0] + (settle_periods + w * periods) * period_s
        end = begin + periods * period_s
        inside = (starts >= begin - 1e-9) & (starts + dt <= end + 1e-9)
        if not inside.any():
            raise OptimizerError(f"no load-cell sample fits in the window [{begin:.3f}, {end:.3f}] s")
        positive_Ns, negative_Ns = signed_integrals(starts[inside] + 0.5 * dt, samples[inside])
        ratio = positive_Ns / negative_Ns if negative_Ns > 0 else math.inf
        results.append(Measurement(ratio, float(samples[inside].mean())))
    return results
