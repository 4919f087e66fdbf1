"""Fit feather coefficients to recorded load-cell runs (`featherstar calibrate`).

Objective: the thrust time series over the first `window_s` of each run (default one stroke
period), from rest, with the simulated feather's root driven by the recorded root angle
(`featherstar.optimizer.calibration.playback`). Least squares (scipy's trust-region reflective, bounds = each
coefficient's physical range from the feather model), residuals in newtons.

Why the first period's time series and not windowed TR / mean thrust: TR and mean thrust are two
numbers per stroke, too few for three coefficients from repeats of one stroke, and they are
nearly insensitive to the added mass (its force averages to zero over a period: docs/model.md).
The time series carries each coefficient in its own shape: drag ∝ rate|rate| peaks at mid
stroke, added mass ∝ acceleration at the stroke's ends, the hinge spring sets when and how fast
the flap folds and unfolds. The flapped feathers are chaotic over many periods (a tiny change
moves the fold timing of later periods), but the first period from rest is deterministic and
repeatable on the bench, so it can be matched sample by sample; windowed metrics are what a
calibration is *checked* against (a fourth, unseen stroke's TR and mean thrust). The plain
feather (no flaps) is not chaotic: several periods from rest match sample by sample too, and
they are what tells the wake laws apart (`--periods`, featherstar.optimizer.calibration.forms).

Start: the residual is not smooth in every coefficient. The hinge stiffness sets when the flaps
fold and hit their stops, so the misfit has a narrow valley around the true value (measured on
the chordwise feather: R² 0.80 at half the true stiffness, 0.997 at it, 0.89 at 1.5 times it) in
which a local least-squares step from the model's default does not land. So each coefficient is
first scanned alone on a log grid (`SCAN_POINTS` values over a decade either side of the start,
inside its range; the others held), keeping the best, twice over (a drag scanned while the hinge
was still wrong compensates for it), then once more on a grid one coarse step either side of the
best (the true value lies between two coarse points: from three real-time chordwise recordings
the least squares started at the coarse point above the true drag stopped in another valley,
drag +56 %, R² 0.984, against R² 0.9987 near the true value), and the least squares starts from
there.

Uncertainty per coefficient: the Gauss–Newton covariance s²(JᵀJ)⁻¹ at the optimum, with s² the
residual variance. Samples 4 ms apart are correlated where the model error (not the load cell's
white noise) dominates, so these are lower bounds; two coefficients that trade off show up as a
large correlation in `correlation`.
"""
from __future__ import annotations

import math
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares

from ...cosim.errors import StepError
from ...cosim.scene.data import scene_from_dict
from ...cosim.scene.specs import parse_value
from ...cosim.scenes import load_scene
from ...cosim.swimmer.run import run_scene
from ...fmu_src.catalog import build_model, build_options
from ..errors import OptimizerError
from .recordings import Recording, check_same_stroke

DEFAULT_COEFFICIENTS = ("drag_coeff", "added_mass_scale", "hinge_stiffness_Nm_rad_m")
# drag_coeff is the constant normal-drag coefficient: fitting it switches the per-point
# oscillatory (Keulegan-Carpenter) drag off, so the fitted value is the one the model uses.
DRAG_COEFF, DRAG_SWITCH = "drag_coeff", "oscillatory_drag"
_GRID_S = 4e-3
# Residuals are thrust averaged over bins of this length (the impulse per bin over its length).
# The added-mass force is proportional to the root's acceleration, which a 250 Hz servo
# read-back cannot resolve (the servo's motor lag makes it change within milliseconds); the
# impulse over a bin depends only on the velocities at its ends, which the read-back does give.
BIN_S = 0.04
#: What a recorded thrust sample is: the mean over the interval before its stamp, or the force at it.
THRUST_SAMPLES = ("interval-mean", "instant")
SCAN_POINTS = 9          # per coefficient and sweep, log-spaced
SCAN_DECADES = 1.0       # the coarse sweeps: a decade either side of the start
SCAN_SWEEPS = 2          # a coefficient scanned while another was still wrong is scanned again
# then one fine sweep, a coarse step either side of the best so far (the true value falls between
# two coarse points, and the least squares from the wrong one can stop in another valley)
FINE_SCAN_DECADES = 2 * SCAN_DECADES / (SCAN_POINTS - 1)


@dataclass(frozen=True)
class Coefficient:
    """A coefficient to fit: its search range (inside the model's physical range) and start."""

    name: str
    low: float
    high: float
    start: float
    unit: str


@dataclass(frozen=True)
class Calibration:
    coefficients: tuple[Coefficient, ...]
    values: dict[str, float]
    sd: dict[str, float]
    correlation: list[list[float]]
    fixed: dict[str, float]
    rms_residual_N: float
    r_squared: float
    per_run_rms_N: dict[str, float]
    window_s: float
    evaluations: int
    wall_s: float
    bin_times_s: np.ndarray
    measured_N: np.ndarray
    simulated_N: np.ndarray
    converged: bool = True
    solver_message: str = ""

    def failure(self, *, sd: bool = True) -> str | None:
        """Why this fit is not a calibration (None when it is): a residual, R², value or (with `sd`)
        sd that is not finite, or a least squares that stopped before converging. Without `sd` an
        infinite sd is left to the caller (featherstar.optimizer.calibration.identify flags it)."""
        stats = {"rms residual": self.rms_residual_N, "R²": self.r_squared,
                 **{f"{k} value": v for k, v in self.values.items()},
                 **({f"{k} sd": v for k, v in self.sd.items()} if sd else {})}
        bad = [f"{name} {value}" for name, value in stats.items() if not math.isfinite(value)]
        if bad:
            return f"{', '.join(bad)} (is a recorded sample absurd, or a coefficient without effect on the thrust?)"
        if not self.converged:
            return f"the least squares did not converge ({self.solver_message})"
        return None

    def parameter_set(self) -> dict[str, float]:
        """Scene overrides ("feather.NAME": value) that make a scene use the calibrated feather."""
        return {f"feather.{k}": v for k, v in {**self.fixed, **self.values}.items()}

    def as_dict(self) -> dict[str, Any]:
        return {
            "parameters": self.parameter_set(),
            "coefficients": [{"name": c.name, "value": self.values[c.name], "sd": self.sd[c.name], "unit": c.unit,
                              "range": [c.low, c.high], "start": c.start} for c in self.coefficients],
            "correlation": self.correlation,
            "fixed": self.fixed,
            "fit": {"objective": f"thrust averaged over {BIN_S * 1e3:g} ms bins over the first {self.window_s:g} s "
                                 "of each run, from rest, root driven by the recorded angle; least squares", "rms_residual_N": self.rms_residual_N,
                    "r_squared": self.r_squared, "per_run_rms_N": self.per_run_rms_N,
                    "simulations": self.evaluations, "wall_s": self.wall_s},
        }


def feather_block(scene: str) -> dict[str, Any]:
    """The scene's feather block (kind fmu, model feather), as the scene defines it."""
    block = load_scene(scene).to_dict()["blocks"].get("feather")
    if not block or block.get("model") != "feather":
        raise OptimizerError(f"scene '{scene}' has no feather block (kind fmu, model feather) to calibrate")
    return block


def feather_model(block: Mapping[str, Any], overrides: Mapping[str, Any]):
    """The feather model the block builds with the feather.* overrides (morphology, n_units...)."""
    options = dict(block.get("options", {}))
    for key in build_options("feather"):   # every build option (wake, drag rule...), none dropped
        if f"feather.{key}" in overrides:
            options[key] = parse_value(overrides[f"feather.{key}"])
    return build_model("feather", options)


def coefficient_ranges(model, fit: Mapping[str, tuple[float, float] | None]) -> tuple[Coefficient, ...]:
    """Each coefficient's search range: the given (low, high) or the model's physical range;
    a range outside the physical one, an unknown name or a switch is refused."""
    parameters = {p.name: p for p in model.parameters}
    coefficients = []
    for name, bounds in fit.items():
        if name not in parameters:
            raise OptimizerError(f"--fit {name}: the {model.name} model has no such coefficient; it has "
                                 f"{', '.join(p.name for p in model.parameters if p.choices is None)}")
        p = parameters[name]
        if p.choices is not None:
            raise OptimizerError(f"--fit {name}: a switch ({', '.join(map(str, p.choices))}), not a coefficient")
        low, high = bounds if bounds is not None else (p.minimum, p.maximum)
        below = low <= p.minimum if p.exclusive_minimum else low < p.minimum
        if not (math.isfinite(low) and math.isfinite(high) and low < high) or below or high > p.maximum:
            raise OptimizerError(f"--fit {name}={low:g},{high:g}: outside the physical range "
                                 f"{'(' if p.exclusive_minimum else '['}{p.minimum:g}, {p.maximum:g}] {p.unit} "
                                 f"({p.description}), or empty")
        start = min(max(p.default, low), high)
        if start <= 0:
            start = high * 1e-2 if low <= 0 else low
        coefficients.append(Coefficient(name, low, high, start, p.unit))
    return tuple(coefficients)


class _Playback:
    """Simulates the feather driven by the mean recorded root angle; one scene, many parameter sets."""

    def __init__(self, block: Mapping[str, Any], overrides: Mapping[str, Any], recordings: Sequence[Recording],
                 window_s: float, workdir: Path, progress: Callable[[int], None] | None = None) -> None:
        self.overrides = {k: v for k, v in overrides.items() if k.startswith("feather.")}
        self.grid_s = np.arange(0.0, window_s + 1e-9, _GRID_S)
        angle = np.mean([np.interp(self.grid_s, r.time_s, r.angle_rad) for r in recordings], axis=0)
        path = workdir / "root_angle.npz"
        np.savez(path, time_s=self.grid_s, angle_rad=angle)
        self.scene = scene_from_dict({
            "description": "the feather driven by a recorded root angle (calibration)",
            "connections": ["root.angle_rad -> feather.root_angle_rad", "root.rate_rad_s -> feather.root_rate_rad_s",
                            "root.accel_rad_s2 -> feather.root_accel_rad_s2",
                            "tank.flow_speed_m_s -> feather.flow_speed_m_s"],
            "master": {"coupling": "strong", "method": "adams", "rtol": 1e-6, "atol": 1e-8,
                       "t_end_s": float(self.grid_s[-1]), "output_interval_s": 1e-3},
            "metrics": {"thrust": "feather.thrust_N", "angle": "root.angle_rad", "settle_periods": 0,
                        "period_s": float(self.grid_s[-1])},
            "blocks": {"root": {"kind": "python", "factory": "featherstar.optimizer.calibration.playback:RecordedRoot",
                                "parameters": {"path": str(path)}},
                       "feather": dict(block),
                       "tank": {"kind": "constant", "outputs": {"flow_speed_m_s": {"value": 0.0, "unit": "m/s"}}}},
        }, name="calibration")
        self.runs = 0
        self.progress = progress

    def thrust_N(self, parameters: Mapping[str, float]) -> np.ndarray:
        """Simulated thrust on the grid for these feather parameters."""
        self.runs += 1
        if self.progress is not None:
            self.progress(self.runs)
        try:
            result = run_scene(self.scene, {**self.overrides, **{f"feather.{k}": v for k, v in parameters.items()}},
                               outputs=["feather.thrust_N"])
        except StepError as exc:
            raise OptimizerError(f"calibration: the feather with {dict(parameters)} could not be simulated: {exc}") from None
        return np.interp(self.grid_s, result.time, result["feather.thrust_N"])


def default_fit(model) -> dict[str, None]:
    """DEFAULT_COEFFICIENTS that this feather has (a plain feather has no hinge), full ranges."""
    names = {p.name for p in model.parameters}
    return {name: None for name in DEFAULT_COEFFICIENTS if name in names}


def calibrate(recordings: Sequence[Recording], scene: str, overrides: Mapping[str, Any],
              fit: Mapping[str, tuple[float, float] | None] | None = None, *, window_s: float | None = None,
              max_simulations: int = 80, start: Mapping[str, float] | None = None,
              progress: Callable[[int], None] | None = None, require_sd: bool = True,
              thrust_samples: str = "instant") -> Calibration:
    """Least-squares fit of the `fit` coefficients ({name: (low, high) or None for the physical
    range}; default: DEFAULT_COEFFICIENTS) of the scene's feather to the recordings.

    `start` ({name: value}): start the least squares there and skip the scan (a refit on a subset
    of the recordings from the fit on all of them: featherstar.optimizer.calibration.forms).
    `progress(simulations)` is called before each simulation. `require_sd=False` returns a fit
    whose sd is infinite (a coefficient without effect) for the caller to flag, instead of refusing it.
    `thrust_samples`: what a recorded thrust sample is (`measured_thrust_N`)."""
    if not recordings:
        raise OptimizerError("calibrate needs at least one recorded run")
    if window_s is None:
        periods = {r.period_s for r in recordings}
        if None in periods or len(periods) != 1:
            raise OptimizerError("the stroke period of the runs is unknown (no summary.json beside them): give "
                                 "--window-s, e.g. the stroke period")
        window_s = periods.pop()
    if not (math.isfinite(window_s) and window_s > 0):
        raise OptimizerError(f"--window-s {window_s} must be a positive number of seconds")
    short = [r.source for r in recordings if r.time_s[-1] < window_s - 1e-9]
    if short:
        raise OptimizerError(f"{short[0]}: shorter than the fit window ({window_s:g} s)")
    check_same_stroke(recordings, window_s)
    block = feather_block(scene)
    model = feather_model(block, overrides)
    coefficients = coefficient_ranges(model, default_fit(model) if fit is None else fit)
    if start is not None:
        # the start is also each coefficient's scale, so it must not be 0
        coefficients = tuple(replace(c, start=min(max(float(start[c.name]), c.low), c.high))
                             if float(start[c.name]) > 0 else c for c in coefficients)
    names = [c.name for c in coefficients]
    fixed = {DRAG_SWITCH: 0.0} if DRAG_COEFF in names else {}
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="featherstar-calibrate-") as workdir:
        playback = _Playback(block, overrides, recordings, window_s, Path(workdir), progress)
        measured = _binned(np.array([measured_thrust_N(r, playback.grid_s, thrust_samples) for r in recordings]))
        for recording, row in zip(recordings, measured):
            with np.errstate(over="ignore"):
                overflows = not np.isfinite(np.sum(row**2))   # then no least squares can use this run
            if overflows:
                raise OptimizerError(f"{recording.source}: thrust up to {np.max(np.abs(recording.thrust_N)):.3g} N "
                                     "in the fit window cannot be fitted; is a sample corrupt, or the unit wrong?")
        scale = np.array([c.start for c in coefficients])

        def residuals(x: np.ndarray) -> np.ndarray:
            simulated = _binned(playback.thrust_N({**fixed, **dict(zip(names, x * scale))}))
            return (simulated[None, :] - measured).ravel()

        x0 = np.ones(len(coefficients)) if start is not None else _scanned_start(residuals, coefficients, scale)
        try:
            fitted = _least_squares(residuals, x0, coefficients, scale, max_simulations)
        except ValueError as exc:   # scipy refuses residuals that are not finite
            raise OptimizerError(f"calibration failed, nothing written as a parameter set: {exc}") from None
        simulations = playback.runs
    residual = fitted.fun.reshape(measured.shape)
    n_bin = max(1, round(BIN_S / _GRID_S))
    bin_times_s = playback.grid_s[: measured.shape[1] * n_bin].reshape(-1, n_bin).mean(axis=1)
    dof = max(residual.size - len(names), 1)
    variance = float(np.sum(residual**2) / dof)
    sd, correlation = _covariance(fitted.jac, variance, scale)
    total = float(np.sum((measured - measured.mean()) ** 2))
    result = Calibration(
        coefficients=coefficients,
        values={n: float(v) for n, v in zip(names, fitted.x * scale)},
        sd=dict(zip(names, sd)),
        correlation=correlation,
        fixed=fixed,
        rms_residual_N=float(np.sqrt(np.mean(residual**2))),
        r_squared=1.0 - float(np.sum(residual**2)) / total if total > 0 else math.nan,
        per_run_rms_N={r.source: float(np.sqrt(np.mean(row**2))) for r, row in zip(recordings, residual)},
        window_s=float(window_s),
        evaluations=simulations,
        wall_s=time.perf_counter() - started,
        bin_times_s=bin_times_s,
        measured_N=measured,
        simulated_N=measured + residual,
        converged=bool(fitted.status > 0),
        solver_message=str(fitted.message),
    )
    failure = result.failure(sd=require_sd)
    if failure:
        raise OptimizerError(f"calibration failed, nothing written as a parameter set: {failure}")
    return result


def measured_thrust_N(recording: Recording, grid_s: np.ndarray, thrust_samples: str = "instant") -> np.ndarray:
    """The recorded thrust on the grid. "interval-mean": each sample is the mean force over the
    interval before its time stamp, as the bench's integrating (sigma-delta) load cell reports it
    and `featherstar run --hardware` stamps it, so it stands for the interval's middle, half a
    sample interval earlier; "instant": each sample is the force at its stamp. (Read as instant,
    an interval mean lags the recorded angle by half a 5 ms step: with the true model and
    coefficients the playback then missed the emulator's self-law recording by 9.2 mN rms, against
    2.3 mN with the half-step and 1.7 mN of noise: bench/bench_model_form_calibration.py.) The
    default stays "instant" until the stamping of older recordings is settled: the chordwise
    real-time recordings in tests/optimizer/data (made by an older model and master) fit drag
    within 15 % read as instant and 21 % low read as interval means."""
    if thrust_samples not in THRUST_SAMPLES:
        raise OptimizerError(f"--thrust-samples {thrust_samples}: valid: {', '.join(THRUST_SAMPLES)}")
    t = recording.time_s
    if thrust_samples == "interval-mean" and t.size > 1:
        t = t - 0.5 * float(np.median(np.diff(t)))
    return np.interp(grid_s, t, recording.thrust_N)


def predict(recording: Recording, scene: str, overrides: Mapping[str, Any], parameters: Mapping[str, float],
            window_s: float, thrust_samples: str = "instant") -> tuple[np.ndarray, np.ndarray]:
    """(measured, simulated) thrust of one recording in BIN_S bins over the window, the feather
    driven by its recorded root angle with these parameters (a held-out recording's prediction)."""
    block = feather_block(scene)
    with tempfile.TemporaryDirectory(prefix="featherstar-predict-") as workdir:
        playback = _Playback(block, overrides, [recording], window_s, Path(workdir))
        measured = _binned(measured_thrust_N(recording, playback.grid_s, thrust_samples))
        return measured, _binned(playback.thrust_N(parameters))


def _least_squares(residuals, x0: np.ndarray, coefficients: Sequence[Coefficient], scale: np.ndarray,
                   max_simulations: int):
    """Trust-region reflective least squares inside each coefficient's range (units of `scale`)."""
    return least_squares(residuals, x0, method="trf", diff_step=1e-3,
                         bounds=([c.low / s for c, s in zip(coefficients, scale)],
                                 [c.high / s for c, s in zip(coefficients, scale)]),
                         max_nfev=max_simulations, x_scale=1.0)


def _scanned_start(residuals, coefficients: Sequence[Coefficient], scale: np.ndarray) -> np.ndarray:
    """Each coefficient scanned alone (log grid, the others held at their best so far); the best
    point, in units of `scale`. See the module docstring for why."""
    x = np.ones(len(coefficients))
    best = float(np.sum(residuals(x) ** 2))
    coarse = [(False, i, c) for _ in range(SCAN_SWEEPS) for i, c in enumerate(coefficients)]
    for fine, i, c in coarse + [(True, i, c) for i, c in enumerate(coefficients)]:
        if fine:
            grid = x[i] * scale[i] * np.logspace(-FINE_SCAN_DECADES, FINE_SCAN_DECADES, SCAN_POINTS)
        else:
            grid = scale[i] * np.logspace(-SCAN_DECADES, SCAN_DECADES, SCAN_POINTS)
        for value in np.clip(grid, max(c.low, 1e-300), c.high):
            trial = x.copy()
            trial[i] = value / scale[i]
            cost = float(np.sum(residuals(trial) ** 2))
            if cost < best:
                best, x = cost, trial
    return x


def _binned(thrust_N: np.ndarray) -> np.ndarray:
    """Mean thrust over consecutive BIN_S bins of the 4 ms grid (last axis; a partial bin is dropped)."""
    n = max(1, round(BIN_S / _GRID_S))
    usable = thrust_N.shape[-1] // n * n
    return thrust_N[..., :usable].reshape(*thrust_N.shape[:-1], -1, n).mean(axis=-1)


def _covariance(jac: np.ndarray, variance: float, scale: np.ndarray) -> tuple[list[float], list[list[float]]]:
    """Standard deviations (in the coefficients' units) and the correlation matrix from s²(JᵀJ)⁻¹.
    A coefficient without effect (a Jacobian column of zeros: the finite difference did not move
    the thrust) has sd inf and no correlation; the others' covariance is computed without it."""
    n = len(scale)
    norms = np.linalg.norm(jac, axis=0)
    live = np.flatnonzero(norms > 1e-12 * max(float(norms.max(initial=0.0)), 1e-300))
    sd_scaled, correlation = np.full(n, math.inf), np.full((n, n), math.nan)
    try:
        cov = variance * np.linalg.inv(jac[:, live].T @ jac[:, live])
    except np.linalg.LinAlgError:
        return [math.inf] * n, correlation.tolist()
    sd_live = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    sd_scaled[live] = sd_live
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation[np.ix_(live, live)] = cov / np.outer(sd_live, sd_live)
    return [float(s) for s in sd_scaled * scale], [[float(c) for c in row] for row in correlation]
