"""The named search space of the paper's stroke optimizer, bounded by what the servo can do.

The paper optimizes three variables at a fixed period: log10(t_up/t_down),
log10(t_hold_up/t_hold_down) and log10(t_hold/t_move). Their limits "are chosen based on
mechanical limits of the servo motor"; here they are derived, not typed in:

* a ramp may not ask for more than the servo's no-load speed. Ramps are minimum-jerk, whose peak
  rate is 1.875·A/t_ramp, so t_ramp >= 1.875·A/ω_max (0.317 s for a 60° stroke on an MG996R);
* no phase may be shorter than one 50 Hz PWM frame (20 ms): the servo cannot act on it, and a
  zero hold has no logarithm.

The box is the hull of the strokes that meet both limits. Because the ramp limit couples the
up/down split with the move fraction, part of the box is still infeasible (e.g. the most lopsided
split together with the shortest move); `is_feasible` tells, and the optimizer only proposes
feasible points. Extra variables (a morphology ratio, for co-design) pass straight through as
scene overrides named like the variable.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..cosim.swimmer.stroke import MIN_JERK_PEAK_RATE_FACTOR, Stroke, stroke_from_log_ratios
from ..fmu_src.errors import ModelError
from .errors import OptimizerError

LOG_UP_DOWN = "log10_up_down"
LOG_HOLD_UP_DOWN = "log10_hold_up_down"
LOG_HOLD_MOVE = "log10_hold_move"
STROKE_VARIABLES = (LOG_UP_DOWN, LOG_HOLD_UP_DOWN, LOG_HOLD_MOVE)

# Relative slack on the servo limits, so that points on the bounds (the optimizer's favourite
# place) are not rejected by float rounding of the log/exp round trip.
_LIMIT_TOLERANCE = 1e-9


@dataclass(frozen=True)
class ServoLimits:
    """What the stroke servo can follow. Defaults: MG996R at 4.8 V (0.17 s/60° → 6.2 rad/s) driven
    by 50 Hz PWM."""

    max_rate_rad_s: float = 6.2
    min_phase_s: float = 0.02

    def __post_init__(self) -> None:
        if not (math.isfinite(self.max_rate_rad_s) and self.max_rate_rad_s > 0):
            raise OptimizerError(f"servo max_rate_rad_s = {self.max_rate_rad_s!r} must be > 0")
        if not (math.isfinite(self.min_phase_s) and self.min_phase_s > 0):
            raise OptimizerError(f"servo min_phase_s = {self.min_phase_s!r} must be > 0")

    def min_ramp_s(self, amplitude_deg: float) -> float:
        """Shortest minimum-jerk ramp over amplitude_deg whose peak rate the servo can follow."""
        rate_limited = MIN_JERK_PEAK_RATE_FACTOR * math.radians(amplitude_deg) / self.max_rate_rad_s
        return max(rate_limited, self.min_phase_s)

    def min_period_s(self, amplitude_deg: float) -> float:
        return 2.0 * self.min_ramp_s(amplitude_deg) + 2.0 * self.min_phase_s


@dataclass(frozen=True)
class Variable:
    """One optimization variable with its bounds; `name` is also its scene override for extras."""

    name: str
    low: float
    high: float
    unit: str = "1"
    description: str = ""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low) and math.isfinite(self.high)):
            raise OptimizerError(f"variable '{self.name}': bounds [{self.low}, {self.high}] must be finite")
        if self.low >= self.high:
            raise OptimizerError(
                f"variable '{self.name}': bounds are inverted or empty: low {self.low:g} >= high "
                f"{self.high:g}; give them as (low, high)"
            )


@dataclass(frozen=True)
class SearchSpace:
    """Stroke log-ratios at a fixed period, plus optional pass-through variables."""

    period_s: float
    amplitude_deg: float
    servo: ServoLimits
    variables: tuple[Variable, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.variables)

    @property
    def bounds(self) -> list[tuple[float, float]]:
        return [(v.low, v.high) for v in self.variables]

    def point(self, values: Sequence[float]) -> dict[str, float]:
        """Named point from a vector in variable order."""
        return {name: float(value) for name, value in zip(self.names, values, strict=True)}

    def vector(self, point: Mapping[str, float]) -> list[float]:
        self._check_names(point)
        return [float(point[name]) for name in self.names]

    def stroke(self, point: Mapping[str, float]) -> Stroke:
        try:
            return stroke_from_log_ratios(
                self.period_s, *(float(point[name]) for name in STROKE_VARIABLES),
                amplitude_deg=self.amplitude_deg,
            )
        except ModelError as exc:
            raise OptimizerError(f"point {dict(point)} gives no valid stroke: {exc}") from exc

    def overrides(self, point: Mapping[str, float]) -> dict[str, float]:
        """Scene overrides (controller times, amplitude, extra variables) for a point."""
        self._check_names(point)
        result = stroke_overrides(self.stroke(point))
        result.update({name: float(point[name]) for name in self.names if name not in STROKE_VARIABLES})
        return result

    def violations(self, point: Mapping[str, float]) -> list[str]:
        """Why a point is outside the box or beyond the servo; empty when it is feasible."""
        self._check_names(point)
        problems = []
        for v in self.variables:
            value = float(point[v.name])
            slack = _LIMIT_TOLERANCE * max(1.0, abs(v.low), abs(v.high))
            if not (v.low - slack <= value <= v.high + slack):
                problems.append(f"{v.name} = {value:g} outside [{v.low:g}, {v.high:g}]")
        if problems:
            return problems
        stroke = self.stroke(point)
        min_ramp_s = self.servo.min_ramp_s(self.amplitude_deg) * (1 - _LIMIT_TOLERANCE)
        min_phase_s = self.servo.min_phase_s * (1 - _LIMIT_TOLERANCE)
        for name in ("t_up_s", "t_down_s"):
            if getattr(stroke, name) < min_ramp_s:
                problems.append(
                    f"{name} = {getattr(stroke, name):.3f} s is shorter than the servo's "
                    f"{min_ramp_s:.3f} s for a {self.amplitude_deg:g}° ramp"
                )
        for name in ("t_hold_up_s", "t_hold_down_s"):
            if getattr(stroke, name) < min_phase_s:
                problems.append(f"{name} = {getattr(stroke, name):.4f} s is shorter than one servo frame")
        return problems

    def is_feasible(self, point: Mapping[str, float]) -> bool:
        return not self.violations(point)

    def check(self, point: Mapping[str, float]) -> None:
        problems = self.violations(point)
        if problems:
            raise OptimizerError(f"point {dict(point)} is not allowed: " + "; ".join(problems))

    def feasible_mask(self, X: np.ndarray) -> np.ndarray:
        """Vectorized `is_feasible` for rows of X in variable order (used on candidate clouds)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        low, high = np.array(self.bounds).T
        slack = _LIMIT_TOLERANCE * np.maximum(1.0, np.maximum(abs(low), abs(high)))
        inside = np.all((X >= low - slack) & (X <= high + slack), axis=1)
        index = [self.names.index(name) for name in STROKE_VARIABLES]
        t_up, t_hold_up, t_down, t_hold_down = _stroke_times(self.period_s, *X[:, index].T)
        min_ramp_s = self.servo.min_ramp_s(self.amplitude_deg) * (1 - _LIMIT_TOLERANCE)
        min_phase_s = self.servo.min_phase_s * (1 - _LIMIT_TOLERANCE)
        return (
            inside
            & (np.minimum(t_up, t_down) >= min_ramp_s)
            & (np.minimum(t_hold_up, t_hold_down) >= min_phase_s)
        )

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """n feasible points, uniform over the feasible part of the box (rejection sampling)."""
        low, high = np.array(self.bounds).T
        kept: list[np.ndarray] = []
        count = 0
        for _ in range(100):
            batch = low + (high - low) * rng.random((max(4 * n, 256), len(low)))
            feasible = batch[self.feasible_mask(batch)]
            kept.append(feasible)
            count += len(feasible)
            if count >= n:
                return np.concatenate(kept)[:n]
        raise OptimizerError(f"no feasible stroke found in the box {self.describe()['variables']}")

    def describe(self) -> dict:
        """JSON-ready description; two runs with equal descriptions search the same space."""
        return {
            "period_s": self.period_s,
            "amplitude_deg": self.amplitude_deg,
            "servo": {"max_rate_rad_s": self.servo.max_rate_rad_s, "min_phase_s": self.servo.min_phase_s},
            "variables": [
                {"name": v.name, "low": v.low, "high": v.high, "unit": v.unit} for v in self.variables
            ],
        }

    def _check_names(self, point: Mapping[str, float]) -> None:
        unknown = sorted(set(point) - set(self.names))
        missing = [name for name in self.names if name not in point]
        if unknown or missing:
            raise OptimizerError(
                f"point names do not match the space {list(self.names)}: "
                f"unknown {unknown}, missing {missing}"
            )


def _stroke_times(
    period_s: float, log10_up_down: np.ndarray, log10_hold_up_down: np.ndarray, log10_hold_move: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """featherstar.cosim.swimmer.stroke.stroke_from_log_ratios on arrays (t_up, t_hold_up, t_down, t_hold_down)."""
    t_move = period_s / (1.0 + 10.0**log10_hold_move)
    t_hold = period_s - t_move
    up_fraction = 1.0 / (1.0 + 10.0**-log10_up_down)
    hold_up_fraction = 1.0 / (1.0 + 10.0**-log10_hold_up_down)
    return (
        t_move * up_fraction,
        t_hold * hold_up_fraction,
        t_move * (1.0 - up_fraction),
        t_hold * (1.0 - hold_up_fraction),
    )


def stroke_overrides(stroke: Stroke) -> dict[str, float]:
    """The master's controller overrides for a stroke."""
    return {
        "controller.t_up_s": stroke.t_up_s,
        "controller.t_hold_up_s": stroke.t_hold_up_s,
        "controller.t_down_s": stroke.t_down_s,
        "controller.t_hold_down_s": stroke.t_hold_down_s,
        "controller.amplitude_deg": stroke.amplitude_deg,
    }


def symmetric_stroke(period_s: float, amplitude_deg: float = 60.0) -> Stroke:
    """The paper's baseline (0.25 s ramps, 0.5 s holds at 1.5 s), scaled to period_s."""
    return stroke_from_log_ratios(period_s, 0.0, 0.0, math.log10(2.0), amplitude_deg=amplitude_deg)


def stroke_space(
    period_s: float,
    *,
    amplitude_deg: float = 60.0,
    servo: ServoLimits = ServoLimits(),
    bounds: Mapping[str, tuple[float, float]] | None = None,
    extra: Sequence[Variable] = (),
) -> SearchSpace:
    """The paper's three-variable space at a fixed period, with the box the servo allows.

    `bounds` narrows the box per variable; bounds wider than the servo allows, inverted bounds and
    unknown names are errors. `extra` adds pass-through variables (e.g. `feather.width_ratio`).
    """
    if not (math.isfinite(amplitude_deg) and 0 < amplitude_deg <= 180):
        raise OptimizerError(f"amplitude_deg = {amplitude_deg!r} must be in (0, 180]")
    min_ramp_s = servo.min_ramp_s(amplitude_deg)
    min_hold_s = servo.min_phase_s
    min_period_s = servo.min_period_s(amplitude_deg)
    if not (math.isfinite(period_s) and period_s >= min_period_s):
        raise OptimizerError(
            f"period {period_s!r} s is shorter than the servo allows: a {amplitude_deg:g}° "
            f"minimum-jerk ramp needs >= {min_ramp_s:.3f} s at {servo.max_rate_rad_s:g} rad/s and "
            f"each hold >= {min_hold_s:g} s, so the period must be >= {min_period_s:.3f} s"
        )
    up_down = math.log10((period_s - 2 * min_hold_s - min_ramp_s) / min_ramp_s)
    hold_up_down = math.log10((period_s - 2 * min_ramp_s - min_hold_s) / min_hold_s)
    servo_box = {
        LOG_UP_DOWN: (-up_down, up_down),
        LOG_HOLD_UP_DOWN: (-hold_up_down, hold_up_down),
        LOG_HOLD_MOVE: (
            math.log10(2 * min_hold_s / (period_s - 2 * min_hold_s)),
            math.log10((period_s - 2 * min_ramp_s) / (2 * min_ramp_s)),
        ),
    }
    descriptions = {
        LOG_UP_DOWN: "log10(t_up / t_down)",
        LOG_HOLD_UP_DOWN: "log10(t_hold_up / t_hold_down)",
        LOG_HOLD_MOVE: "log10((t_hold_up + t_hold_down) / (t_up + t_down))",
    }
    extra_names = [v.name for v in extra]
    clashes = sorted({n for n in extra_names if extra_names.count(n) > 1 or n in servo_box})
    if clashes:
        raise OptimizerError(f"extra variables repeat a name: {clashes}")
    for name, pair in (bounds or {}).items():
        if name in extra_names:
            raise OptimizerError(f"'{name}' is an extra variable: give its bounds in its Variable")
        if name not in servo_box:
            hint = difflib.get_close_matches(name, list(servo_box), n=1)
            raise OptimizerError(
                f"unknown variable '{name}' in bounds; known: {sorted(servo_box)}"
                + (f" (did you mean '{hint[0]}'?)" if hint else "")
            )
        low, high = (float(b) for b in pair)
        servo_low, servo_high = servo_box[name]
        Variable(name, low, high)  # rejects inverted or non-finite bounds with the standard message
        if low < servo_low - 1e-12 or high > servo_high + 1e-12:
            raise OptimizerError(
                f"bounds [{low:g}, {high:g}] for '{name}' exceed what the servo allows at "
                f"period {period_s:g} s and {amplitude_deg:g}°: [{servo_low:.4g}, {servo_high:.4g}]"
            )
        servo_box[name] = (low, high)
    variables = tuple(
        Variable(name, low, high, "log10(s/s)", descriptions[name]) for name, (low, high) in servo_box.items()
    ) + tuple(extra)
    space = SearchSpace(period_s, amplitude_deg, servo, variables)
    probe = space.point([v.low + 0.5 * (v.high - v.low) for v in variables])
    if bounds and not space.is_feasible(probe):
        space.sample(np.random.default_rng(0), 1)  # raises when the narrowed box holds no stroke
    return space
