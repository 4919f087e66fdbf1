"""One measured experiment: run an objective, read it through the load cell, compute the metrics.

Noise is seeded per experiment from (seed, stream, index), not from a shared generator, so an
evaluation draws the same noise whether the run was interrupted and resumed or not, and whether it
ran in this process or in a sweep worker.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .errors import OptimizerError
from .loadcell import LoadCell, Measurement, measure
from .objective import Objective, Overrides

# Noise streams: one per kind of experiment, so validation noise never repeats iteration noise.
ITERATION_STREAM = 0
VALIDATION_STREAM = 1
SWEEP_STREAM = 2


@dataclass(frozen=True)
class MeasurementPlan:
    """How an experiment is measured: sensor, settling, measured periods, noise seed."""

    load_cell: LoadCell = field(default_factory=LoadCell)
    settle_periods: int = 3
    periods: int = 5
    seed: int = 0

    def __post_init__(self) -> None:
        # Refused here, not in the first worker: a negative settling would measure another window,
        # zero periods nothing, a negative seed fails inside numpy.
        for name, value, least in (("settle_periods", self.settle_periods, 0), ("periods", self.periods, 1),
                                   ("seed", self.seed, 0)):
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise OptimizerError(f"{name} = {value!r} must be a whole number >= {least}")

    def run_length_s(self, period_s: float, *, windows: int = 1, periods: int | None = None) -> float:
        """Settling plus `windows` × `periods` periods, and one extra load-cell sample so the last
        window's final sample is complete."""
        periods = self.periods if periods is None else periods
        return (self.settle_periods + windows * periods) * period_s + 2.0 / self.load_cell.sample_rate_hz

    def describe(self) -> dict:
        return {
            "noise_sd_N": self.load_cell.noise_sd_N,
            "sample_rate_hz": self.load_cell.sample_rate_hz,
            "settle_periods": self.settle_periods,
            "periods": self.periods,
            "seed": self.seed,
        }


@dataclass(frozen=True)
class Evaluation:
    thrust_ratio: float
    mean_thrust_N: float
    sim_wall_s: float


@dataclass(frozen=True)
class Validation:
    """The paper's validation: `repeats` sets of `periods` cycles; mean and sample sd over the sets."""

    thrust_ratio: float
    thrust_ratio_sd: float
    mean_thrust_N: float
    mean_thrust_sd_N: float
    repeats: tuple[Measurement, ...]
    sim_wall_s: float

    def as_dict(self) -> dict:
        return {
            "thrust_ratio": self.thrust_ratio,
            "thrust_ratio_sd": self.thrust_ratio_sd,
            "mean_thrust_N": self.mean_thrust_N,
            "mean_thrust_sd_N": self.mean_thrust_sd_N,
            "repeats": [{"thrust_ratio": m.thrust_ratio, "mean_thrust_N": m.mean_thrust_N} for m in self.repeats],
        }


def noise_rng(seed: int, stream: int, index: Sequence[int]) -> np.random.Generator:
    return np.random.default_rng([seed, stream, *index])


def run_measured(
    objective: Objective,
    overrides: Overrides,
    period_s: float,
    plan: MeasurementPlan,
    rng: np.random.Generator,
    *,
    windows: int = 1,
    periods: int | None = None,
) -> tuple[list[Measurement], float]:
    """Run once, long enough for settling plus `windows` × `periods` periods; measure each window."""
    periods = plan.periods if periods is None else periods
    trace = objective(overrides, plan.run_length_s(period_s, windows=windows, periods=periods))
    measurements = measure(
        trace.time_s, trace.thrust_N, period_s, plan.load_cell, rng,
        settle_periods=plan.settle_periods, periods=periods, windows=windows,
    )
    return measurements, trace.wall_time_s


def evaluate(
    objective: Objective, overrides: Overrides, period_s: float, plan: MeasurementPlan, stream: int, index: Sequence[int]
) -> Evaluation:
    (measurement,), wall_s = run_measured(objective, overrides, period_s, plan, noise_rng(plan.seed, stream, index))
    return Evaluation(measurement.thrust_ratio, measurement.mean_thrust_N, wall_s)


def validate(
    objective: Objective,
    overrides: Overrides,
    period_s: float,
    plan: MeasurementPlan,
    index: Sequence[int],
    *,
    repeats: int = 10,
    periods: int = 5,
) -> Validation:
    """One long run cut into `repeats` consecutive sets, like the bench's continuous flapping."""
    measurements, wall_s = run_measured(
        objective, overrides, period_s, plan, noise_rng(plan.seed, VALIDATION_STREAM, index),
        windows=repeats, periods=periods,
    )
    ratios = np.array([m.thrust_ratio for m in measurements])
    thrusts = np.array([m.mean_thrust_N for m in measurements])
    ddof = 1 if repeats > 1 else 0
    return Validation(
        thrust_ratio=float(ratios.mean()),
        thrust_ratio_sd=float(ratios.std(ddof=ddof)) if np.all(np.isfinite(ratios)) else math.nan,
        mean_thrust_N=float(thrusts.mean()),
        mean_thrust_sd_N=float(thrusts.std(ddof=ddof)),
        repeats=tuple(measurements),
        sim_wall_s=wall_s,
    )
