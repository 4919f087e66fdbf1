"""A bench study's surrogate that learns the simulation's bias: bench TR = ρ · simulation + discrepancy.

The seeded prior (`featherstar.optimizer.bench.sim_prior`) transfers *where* the simulation's good
strokes are and then forgets the simulation. Here the bench study keeps it as the mean of its
model, in the form of Kennedy & O'Hagan (2001):

    TR_bench(x) = ρ · s(x) + δ(x) + noise

- s(x), the simulation's TR at stroke x: `SimulationModel`, a GP (skopt's: constant × Matérn-5/2
  ARD + white noise, normalised y) fitted to the simulated study's evaluations *plus one
  simulation of every stroke the bench measured*. The caller runs those simulations (the
  optimizer never owns a simulation loop) and tells them with `tell_simulation`; the GP is what
  the acquisition reads at its thousands of candidates, so the simulation is run once per bench
  iteration, not once per candidate. Its own posterior sd enters the model's sd (scaled by ρ).
- δ(x), the discrepancy: a GP of the same form on the residuals y − ρ · s(x) at the bench's
  points (constant mean: the residuals' mean). Its amplitude, length scales and noise are fitted
  by maximum marginal likelihood at every tell: where the bench agrees with the simulation the
  residuals are flat, δ learns a small amplitude and the model follows the simulation between
  bench points; where they differ δ grows and the bench data take over. With a handful of
  points the unconstrained fit explains the bench's noise as structure (measured: white noise
  → 0 and length scales at skopt's 0.01 bound after 10 bench runs), so two bounds are fixed
  by the bench, not fitted:
  * the white noise's sd is at least `noise_floor_sd` (TR), the bench's measured repeatability
    (the same stroke after different strokes; `bench/bench_loop_prior.py` measures it): a
    residual that a repeat of the same stroke would not reproduce is not discrepancy;
  * every length scale is at least DELTA_MIN_LENGTH_SCALE = 0.1 of its variable's range (the
    search box is the unit cube here): strokes closer than that are the same stroke as far as
    the study resolves them (the seeded prior's MIN_SEPARATION, and the candidates' local
    clouds of sd 0.05), so structure on that scale cannot be told from noise with a few runs.
- ρ: the simulation's scale (the model's TR can be off by a factor, README: 1.73 vs ≈ 4), the
  posterior *mean* over a grid on [0, RHO_MAX] of δ's marginal likelihood (in TR units, δ's
  hyperparameters profiled: refitted at every grid value) times a normal prior N(1,
  RHO_PRIOR_SD²), held at 1 (trust the simulation's scale) until MIN_POINTS_FOR_RHO bench points
  exist. Not the mode: with a few noisy points the likelihood is nearly flat in ρ and its mode
  lands at whichever grid end the noise favours (measured: 2.5, 0, 0, 2.5, 0 over five
  studies); the mean stays near the prior until the data speak, and moves to 0 when they do (a
  simulation that predicts nothing: ρ = 0 is a bench-only GP with a constant mean).

Acquisition: MATLAB's expected-improvement-plus (`featherstar.optimizer.acquisition`) on this
model: the incumbent is the evaluated stroke with the best posterior mean, the over-exploitation
test compares the model's sd with the noise sd δ estimated, and a retry inflates δ's variance.

Initial design. δ is identified by bench points alone: from one point it is a constant, the
model's shape is the simulation's, and expected improvement asks at the simulation's optimum
again and again (measured: 5-7 of 10 strokes within 5 % of the range of the first, on a bench
whose wake reverses the simulation's ranking inside its optimum region; docs/bench-loop.md). A
study therefore measures an initial design before asking the model: the simulated study's best
strokes kept 10 % of each range apart (`SimPrior.initial_points`, the seeded prior's design), so
δ's first fit has contrasts inside the region the simulation calls good. Asked before any bench
data, the optimizer proposes the simulation's best stroke.
Deterministic for a seed and a history (randomness seeded by (seed, points told)), so a resumed
study asks what the uninterrupted one would have.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
from threadpoolctl import threadpool_limits
from skopt.learning import GaussianProcessRegressor
from skopt.learning.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel
from skopt.space import Real, Space
from skopt.utils import cook_estimator, normalize_dimensions

from ..acquisition import (
    DEFAULT_EXPLORATION_RATIO, DEFAULT_MAX_RETRIES, Proposal, expected_improvement, noise_sd,
    with_more_variance_between_observations,
)
from ..bayes import Estimate
from ..errors import OptimizerError
from ..space import SearchSpace

RHO_MAX = 2.5
RHO_GRID = np.linspace(0.0, RHO_MAX, 11)   # steps of 0.25
RHO_PRIOR_SD = 0.5   # a factor of 2 in the simulation's TR variation is 2 sd
MIN_POINTS_FOR_RHO = 3
#: δ's smallest length scale, as a fraction of each variable's range (module doc).
DELTA_MIN_LENGTH_SCALE = 0.1
DELTA_MAX_LENGTH_SCALE = 100.0   # skopt's: a flat direction
#: The white noise's sd floor when the bench's repeatability was not measured: the emulator's
#: same stroke back to back repeats to 1 % (docs/bench-loop.md); measure yours (noise_floor_sd).
DEFAULT_NOISE_FLOOR_TR = 0.01
_GLOBAL_CANDIDATES = 2000
_LOCAL_CANDIDATES = 300
_LOCAL_CENTRES = 3
_LOCAL_SD = 0.05   # of each variable's range


def _gp(space: Space, seed: int, restarts: int = 2) -> GaussianProcessRegressor:
    gp = cook_estimator("GP", space=space, random_state=seed, noise="gaussian")
    gp.set_params(n_restarts_optimizer=restarts)
    return gp


def _delta_gp(n_dims: int, y: np.ndarray, noise_floor_sd: float, seed: int,
              restarts: int = 2) -> GaussianProcessRegressor:
    """δ's GP for residuals y: skopt's form (constant × Matérn-5/2 ARD + white noise, normalised y)
    with length scales >= DELTA_MIN_LENGTH_SCALE and a white-noise sd >= noise_floor_sd (TR). The
    GP normalises y by its sd, so the floor is set in those units for these y."""
    scale = float(np.std(y)) if len(y) > 1 and np.std(y) > 0 else 1.0
    floor = (noise_floor_sd / scale) ** 2
    white = WhiteKernel(noise_level=max(floor, min(1.0, 10 * floor)),
                        noise_level_bounds=(floor, max(1e5, 10 * floor)))
    kernel = ConstantKernel(1.0, (0.01, 1000.0)) * Matern(
        length_scale=np.ones(n_dims), length_scale_bounds=[(DELTA_MIN_LENGTH_SCALE, DELTA_MAX_LENGTH_SCALE)] * n_dims,
        nu=2.5) + white
    return GaussianProcessRegressor(kernel=kernel, normalize_y=True, noise="gaussian",
                                    n_restarts_optimizer=restarts, random_state=seed)


def _fit(gp: GaussianProcessRegressor, X: np.ndarray, y: np.ndarray) -> GaussianProcessRegressor:
    # One BLAS thread: these matrices are a few dozen wide (see featherstar.optimizer.bayes).
    with warnings.catch_warnings(), threadpool_limits(limits=1, user_api="blas"):
        warnings.simplefilter("ignore")   # a length scale on its bound
        return gp.fit(X, y)


def log_evidence_tr(gp: GaussianProcessRegressor) -> float:
    """A fitted GP's log marginal likelihood of its data in their own units: sklearn's value is of
    the normalised y, which differs by n · log(sd(y)) (the Jacobian of the normalisation)."""
    n = len(gp.y_train_)
    return float(gp.log_marginal_likelihood_value_) - n * math.log(float(gp.y_train_std_))


class SimulationModel:
    """The simulation's TR at any stroke: a GP on simulated (stroke, TR) pairs. Points told again
    (a stroke simulated twice) are kept once, with their latest value."""

    def __init__(self, space: SearchSpace, points: Sequence[Mapping[str, float]], values: Sequence[float],
                 *, seed: int = 0) -> None:
        if len(points) != len(values) or not points:
            raise OptimizerError(f"a simulation model needs simulated evaluations ({len(points)} points, "
                                 f"{len(values)} values)")
        self.space = space
        self.skspace = Space(normalize_dimensions([Real(v.low, v.high, name=v.name) for v in space.variables]))
        self._seed = seed
        self._data: dict[tuple[float, ...], float] = {}
        self.n_study = len(points)
        for point, value in zip(points, values):
            self._data[tuple(space.vector(point))] = _finite(value, point)
        self._gp: GaussianProcessRegressor | None = None

    def transform(self, X: np.ndarray) -> np.ndarray:
        return np.asarray(self.skspace.transform(np.atleast_2d(X).tolist()))

    def add(self, point: Mapping[str, float], value: float) -> None:
        self._data[tuple(self.space.vector(point))] = _finite(value, point)
        self._gp = None

    @property
    def n_points(self) -> int:
        return len(self._data)

    def vectors(self) -> np.ndarray:
        """The simulated strokes, as rows of the space's vectors."""
        return np.array(list(self._data))

    def has(self, point: Mapping[str, float]) -> bool:
        return tuple(self.space.vector(point)) in self._data

    def predict(self, X: np.ndarray, return_std: bool = False):
        """TR (and its posterior sd) at rows of stroke vectors, in the space's units."""
        if self._gp is None:
            X_data = self.transform(np.array(list(self._data)))
            self._gp = _fit(_gp(self.skspace, self._seed), X_data, np.array(list(self._data.values())))
        return self._gp.predict(self.transform(X), return_std=return_std)

    def best_point(self, maximize: bool) -> dict[str, float]:
        """The simulated stroke with the best posterior mean (not the luckiest noisy one)."""
        X = np.array(list(self._data))
        mean = self.predict(X)
        return self.space.point(X[int(np.argmax(mean) if maximize else np.argmin(mean))])

    def holdout_error(self, fraction: float = 0.25, seed: int = 0) -> dict:
        """How well the GP predicts simulations it was not fitted on: refit on a random
        (1 - fraction) of the points, predict the rest (TR units)."""
        X, y = np.array(list(self._data)), np.array(list(self._data.values()))
        rng = np.random.default_rng(seed)
        held = rng.permutation(len(y))[: max(1, int(round(fraction * len(y))))]
        kept = np.setdiff1d(np.arange(len(y)), held)
        gp = _fit(_gp(self.skspace, self._seed), self.transform(X[kept]), y[kept])
        error = gp.predict(self.transform(X[held])) - y[held]
        return {"points_fitted": int(len(kept)), "points_held_out": int(len(held)),
                "rms_error": float(np.sqrt(np.mean(error ** 2))), "max_abs_error": float(np.max(np.abs(error))),
                "simulated_tr_sd": float(np.std(y))}


@dataclass(frozen=True)
class _Model:
    """Posterior of ρ · s + δ in the minimising convention (sign · TR), in transformed coordinates."""

    sign: float
    rho: float
    delta: GaussianProcessRegressor
    sim_mean: np.ndarray   # sign-free TR of s at the rows predicted
    sim_sd: np.ndarray

    def predict(self, Xt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mean, sd = self.delta.predict(Xt, return_std=True)
        return self.sign * self.rho * self.sim_mean + mean, np.sqrt(sd ** 2 + (self.rho * self.sim_sd) ** 2)


class DiscrepancyOptimizer:
    """Ask/tell Bayesian optimizer whose surrogate is ρ · simulation + discrepancy (module doc).

    The order per stroke: `ask`, simulate it and `tell_simulation`, measure it and `tell`; a
    bench value told for a stroke whose simulation was not told is refused."""

    def __init__(self, space: SearchSpace, simulation: SimulationModel, *, maximize: bool = True,
                 exploration_ratio: float = DEFAULT_EXPLORATION_RATIO, seed: int = 0,
                 noise_floor_sd: float = DEFAULT_NOISE_FLOOR_TR) -> None:
        """`noise_floor_sd`: the bench's repeatability in TR (sd of one stroke measured after
        different strokes), the least noise δ may assume (module doc)."""
        if not exploration_ratio >= 0:
            raise OptimizerError(f"exploration_ratio = {exploration_ratio} must be >= 0")
        if not (math.isfinite(noise_floor_sd) and noise_floor_sd > 0):
            raise OptimizerError(f"noise_floor_sd = {noise_floor_sd!r} must be a positive TR")
        self.noise_floor_sd = float(noise_floor_sd)
        self.space = space
        self.simulation = simulation
        self.maximize = maximize
        self.exploration_ratio = exploration_ratio
        self.seed = seed
        self.n_initial_points = 1   # the model is defined from the first bench point (module doc: initial design)
        self.last_proposal: Proposal | None = None
        self._sign = -1.0 if maximize else 1.0
        self._X: list[list[float]] = []
        self._y: list[float] = []
        self._rho = 1.0
        self._delta: GaussianProcessRegressor | None = None

    @property
    def n_told(self) -> int:
        return len(self._y)

    def tell_simulation(self, point: Mapping[str, float], value: float) -> None:
        """The simulation's TR at a stroke (the caller ran it); the simulation model refits lazily."""
        self.simulation.add(point, value)
        self._delta = None

    def tell(self, point: Mapping[str, float], value: float) -> None:
        self.tell_many([point], [value])

    def tell_many(self, points: Sequence[Mapping[str, float]], values: Sequence[float]) -> None:
        """Bench TR at strokes whose simulation was told; ρ and δ are refitted once for the batch."""
        if len(points) != len(values):
            raise OptimizerError(f"{len(points)} points but {len(values)} values")
        for point, value in zip(points, values):
            vector = self.space.vector(point)
            for v, x in zip(self.space.variables, vector):
                if not v.low <= x <= v.high:
                    raise OptimizerError(f"{v.name} = {x:g} is outside [{v.low:g}, {v.high:g}]")
            if not self.simulation.has(point):
                raise OptimizerError(f"bench TR told at {dict(point)} before its simulation: call tell_simulation "
                                     "first (the discrepancy is bench minus simulation)")
            self._X.append(vector)
            self._y.append(_finite(value, point))
        self._delta = None

    def _fitted(self) -> tuple[GaussianProcessRegressor, np.ndarray, np.ndarray]:
        """δ's GP (fitted on the signed residuals), the transformed bench points and the residuals."""
        X = np.array(self._X)
        Xt = self.simulation.transform(X)
        s = self.simulation.predict(X)
        y = np.array(self._y)
        d = Xt.shape[1]
        if self._delta is None:
            rho = 1.0
            if len(y) >= MIN_POINTS_FOR_RHO:
                rho = float(np.sum(self.rho_posterior() * RHO_GRID))
            self._rho = rho
            residuals = self._sign * (y - rho * s)
            self._delta = _fit(_delta_gp(d, residuals, self.noise_floor_sd, self.seed), Xt, residuals)
        return self._delta, Xt, self._sign * (y - self._rho * s)

    def rho_posterior(self) -> np.ndarray:
        """ρ's posterior on RHO_GRID (sums to 1): δ's marginal likelihood of the residuals at each
        ρ, in TR units, its hyperparameters refitted there (profiled), times the prior
        N(1, RHO_PRIOR_SD²)."""
        X = np.array(self._X)
        Xt = self.simulation.transform(X)
        s = self.simulation.predict(X)
        y = np.array(self._y)
        log_post = []
        for r in RHO_GRID:
            residuals = self._sign * (y - r * s)
            gp = _fit(_delta_gp(Xt.shape[1], residuals, self.noise_floor_sd, self.seed, restarts=1), Xt, residuals)
            log_post.append(log_evidence_tr(gp) - 0.5 * ((r - 1.0) / RHO_PRIOR_SD) ** 2)
        log_post = np.array(log_post)
        weights = np.exp(log_post - log_post.max())
        return weights / weights.sum()

    @property
    def rho(self) -> float:
        """The simulation's fitted scale (1 before MIN_POINTS_FOR_RHO bench points)."""
        if self._y:
            self._fitted()
        return self._rho

    def _model(self, delta: GaussianProcessRegressor, X: np.ndarray) -> tuple[_Model, np.ndarray]:
        mean, sd = self.simulation.predict(X, return_std=True)
        return _Model(self._sign, self._rho, delta, mean, sd), self.simulation.transform(X)

    def ask(self) -> dict[str, float]:
        with threadpool_limits(limits=1, user_api="blas"):
            return self._ask()

    def _ask(self) -> dict[str, float]:
        if not self._y:
            self.last_proposal = None
            return self.simulation.best_point(self.maximize)
        rng = np.random.default_rng([self.seed, self.n_told])
        delta, Xt, residuals = self._fitted()
        X = np.array(self._X)
        candidates = self._candidates(rng, X)
        at_evaluated, _ = self._model(delta, X)
        at_candidates, Ct = self._model(delta, candidates)
        sigma = noise_sd(delta)
        model, retry = delta, 0
        while True:
            evaluated = _Model(self._sign, self._rho, model, at_evaluated.sim_mean, at_evaluated.sim_sd)
            best_mean = float(np.min(evaluated.predict(Xt)[0]))
            mean, sd = _Model(self._sign, self._rho, model, at_candidates.sim_mean, at_candidates.sim_sd).predict(Ct)
            ei = expected_improvement(mean, sd, best_mean)
            index = int(np.argmax(ei))
            overexploiting = bool(sd[index] < self.exploration_ratio * sigma)
            if not overexploiting or retry == DEFAULT_MAX_RETRIES:
                self.last_proposal = Proposal(index, float(ei[index]), float(sd[index]), sigma, retry, overexploiting)
                return self.space.point(candidates[index])
            retry += 1
            model = with_more_variance_between_observations(delta, Xt, residuals, 2.0 ** retry)

    def best(self) -> Estimate | None:
        """The bench-evaluated stroke with the best posterior mean (None before any bench data)."""
        if not self._y:
            return None
        delta, Xt, _ = self._fitted()
        X = np.array(self._X)
        model, _ = self._model(delta, X)
        mean, sd = model.predict(Xt)
        index = int(np.argmin(mean))
        return Estimate(self.space.point(X[index]), self._sign * float(mean[index]), float(sd[index]))

    def noise_sd(self) -> float | None:
        """δ's estimate of the bench noise, in TR."""
        return noise_sd(self._fitted()[0]) if self._y else None

    def predict(self, points: Sequence[Mapping[str, float]]) -> tuple[np.ndarray, np.ndarray]:
        """The model's bench TR and sd at strokes (sign-free TR)."""
        X = np.array([self.space.vector(p) for p in points])
        if not self._y:
            mean, sd = self.simulation.predict(X, return_std=True)
            return mean, sd
        delta, _, _ = self._fitted()
        model, Xt = self._model(delta, X)
        mean, sd = model.predict(Xt)
        return self._sign * mean, sd

    def describe(self) -> dict:
        return {"rho": self.rho, "bench_points": self.n_told, "noise_floor_sd": self.noise_floor_sd,
                "simulated_points": self.simulation.n_points,
                "delta_kernel": None if self._delta is None else str(self._delta.kernel_),
                # the kernel prints its white noise as 0 (skopt moves it to noise_ after the fit)
                "delta_noise_sd": None if self._delta is None else noise_sd(self._delta)}

    def _candidates(self, rng: np.random.Generator, X: np.ndarray) -> np.ndarray:
        """Uniform over the feasible space, plus local clouds around the best-mean bench points and
        around the simulation's best points (where the model's optimum usually lies)."""
        low, high = np.array(self.space.bounds).T
        mean, _ = self.predict([self.space.point(x) for x in X])
        sim_X = self.simulation.vectors()
        sim_mean = self.simulation.predict(sim_X)
        order = np.argsort(self._sign * mean)[:_LOCAL_CENTRES]
        sim_order = np.argsort(self._sign * sim_mean)[:_LOCAL_CENTRES]
        centres = np.concatenate([X[order], sim_X[sim_order]])
        local = (centres[:, None, :] + _LOCAL_SD * (high - low)
                 * rng.standard_normal((len(centres), _LOCAL_CANDIDATES, len(low)))).reshape(-1, len(low)).clip(low, high)
        return np.concatenate([self.space.sample(rng, _GLOBAL_CANDIDATES), local[self.space.feasible_mask(local)]])


def _finite(value: float, point: Mapping[str, float]) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise OptimizerError(f"TR {value!r} at {dict(point)} is not finite")
    return value
