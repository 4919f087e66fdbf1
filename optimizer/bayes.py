"""Bayesian optimization of the stroke: an ask/tell optimizer and a resumable driver around it.

`StrokeOptimizer` wraps `skopt.Optimizer` for what skopt does well (transformed space, the
Matérn-5/2 ARD GP with estimated noise, history) and replaces its acquisition with MATLAB's
expected-improvement-plus (`featherstar.optimizer.acquisition`). The caller owns the loop: ask a point, run the
experiment however it likes (simulation, bench, cluster), tell the result.

Everything random in `ask` is seeded from (seed, number of points told so far), so an optimizer
rebuilt from a log proposes exactly what the uninterrupted run would have.

`optimize` is the driver: it replays the JSONL log, then asks, evaluates, appends, tells until the
budget is spent. Objective values are the paper's thrust ratio, maximized or minimized.
"""
from __future__ import annotations

import copy
import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
from skopt import Optimizer
from skopt.space import Real
from threadpoolctl import threadpool_limits

from ..fmu_src.errors import FeatherstarError

from .acquisition import DEFAULT_EXPLORATION_RATIO, Proposal, expected_improvement_plus, incumbent, noise_sd
from .errors import OptimizerError
from .evaluation import ITERATION_STREAM, Evaluation, MeasurementPlan, evaluate
from .executor import Executor, InlineExecutor
from .log import ExperimentLog
from .objective import Objective, preflight
from .resume import check_log
from .space import SearchSpace
from .study_log import check_in_order, study_entries

# MATLAB bayesopt's NumSeedPoints default: random points before the GP takes over.
DEFAULT_INITIAL_POINTS = 4
DEFAULT_ITERATIONS = 30
# Candidate clouds for the acquisition: uniform over the feasible space plus local clouds around
# the best evaluated points, where EI's maximum usually lies (sd in the GP's [0, 1] coordinates).
_GLOBAL_CANDIDATES = 2000
_LOCAL_CANDIDATES = 300
_LOCAL_CENTRES = 3
_LOCAL_SD = 0.05


def _small_blas():
    """GP matrices here are at most a few hundred wide: OpenBLAS threads only add synchronisation
    (a 30-point fit takes 0.65 s with 2 threads on a busy 2-core machine, 0.07 s with one)."""
    return threadpool_limits(limits=1, user_api="blas")


@dataclass(frozen=True)
class Estimate:
    """The evaluated point with the best posterior mean; value and sd of the noise-free objective."""

    point: dict[str, float]
    value: float
    sd: float


class StrokeOptimizer:
    """Ask/tell Bayesian optimizer over a `SearchSpace`; values are in objective units (TR)."""

    def __init__(
        self,
        space: SearchSpace,
        *,
        maximize: bool = True,
        n_initial_points: int = DEFAULT_INITIAL_POINTS,
        exploration_ratio: float = DEFAULT_EXPLORATION_RATIO,
        seed: int = 0,
    ) -> None:
        if n_initial_points < 1:
            raise OptimizerError(f"n_initial_points = {n_initial_points} must be >= 1")
        if not exploration_ratio >= 0:
            raise OptimizerError(f"exploration_ratio = {exploration_ratio} must be >= 0")
        self.space = space
        self.maximize = maximize
        self.n_initial_points = n_initial_points
        self.exploration_ratio = exploration_ratio
        self.seed = seed
        self.last_proposal: Proposal | None = None
        self.last_proposals: list[Proposal | None] = []
        # skopt computes its own next point inside tell(); one sample keeps that unused work cheap.
        self._skopt = Optimizer(
            [Real(v.low, v.high, name=v.name) for v in space.variables],
            base_estimator="GP",
            n_initial_points=n_initial_points,
            acq_func="EI",
            acq_optimizer="sampling",
            acq_optimizer_kwargs={"n_points": 1},
            random_state=seed,
        )

    @property
    def n_told(self) -> int:
        return len(self._skopt.yi)

    def ask(self) -> dict[str, float]:
        return self.ask_batch(1)[0]

    def ask_batch(self, size: int) -> list[dict[str, float]]:
        """`size` points to evaluate at once; the first is what `ask` would return.

        Constant liar: each further point is asked of a copy of the optimizer told that the points
        before it scored the best value seen so far (an optimistic lie, so EI there collapses and
        the batch spreads out). The lies never reach this optimizer. Deterministic for a given
        seed, history and size, and the first j points of a batch of k are the batch of j.
        `last_proposals` holds each point's acquisition details (None for random points).
        """
        if size < 1:
            raise OptimizerError(f"batch size {size} must be >= 1")
        with _small_blas():
            if not self._skopt.models:
                # The initial design: random points, seeded as the sequential asks would be.
                self.last_proposals = [None] * size
                self.last_proposal = None
                return [self.space.point(self.space.sample(np.random.default_rng([self.seed, self.n_told + j]), 1)[0])
                        for j in range(size)]
            points = [self._ask()]
            proposals = [self.last_proposal]
            if size > 1:
                shadow = copy.copy(self)
                shadow._skopt = self._skopt.copy(random_state=self.seed)
                lie = min(self._skopt.yi) * (-1.0 if self.maximize else 1.0)  # best seen, in TR
                for _ in range(size - 1):
                    shadow.tell(points[-1], lie)
                    points.append(shadow._ask())
                    proposals.append(shadow.last_proposal)
            self.last_proposals = proposals
            self.last_proposal = proposals[0]
            return points

    def _ask(self) -> dict[str, float]:
        rng = np.random.default_rng([self.seed, self.n_told])
        if self.n_told < self.n_initial_points or not self._skopt.models:
            self.last_proposal = None
            return self.space.point(self.space.sample(rng, 1)[0])
        gp = self._skopt.models[-1]
        X = self._transform(np.asarray(self._skopt.Xi))
        y = np.asarray(self._skopt.yi)
        candidates = self._candidates(rng, gp, X)
        proposal = expected_improvement_plus(
            gp, X, y, self._transform(candidates), exploration_ratio=self.exploration_ratio
        )
        self.last_proposal = proposal
        return self.space.point(candidates[proposal.index])

    def tell(self, point: Mapping[str, float], value: float) -> None:
        self.tell_many([point], [value])

    def tell_many(self, points: Sequence[Mapping[str, float]], values: Sequence[float]) -> None:
        """Add results; the GP is refitted once for the whole batch (fast log replay)."""
        if len(points) != len(values):
            raise OptimizerError(f"{len(points)} points but {len(values)} values")
        if not points:
            return
        vectors = []
        for point, value in zip(points, values):
            if not math.isfinite(value):
                raise OptimizerError(f"objective value {value!r} at {dict(point)} is not finite")
            vector = self.space.vector(point)
            for v, x in zip(self.space.variables, vector):
                if not v.low <= x <= v.high:
                    raise OptimizerError(f"{v.name} = {x:g} is outside [{v.low:g}, {v.high:g}]")
            vectors.append(vector)
        signed = [(-1.0 if self.maximize else 1.0) * float(v) for v in values]
        with warnings.catch_warnings(), _small_blas():
            # The GP's hyperparameter search warns when a length scale sits on its bound.
            warnings.simplefilter("ignore")
            self._skopt.tell(vectors, signed)

    def best(self) -> Estimate | None:
        """Best posterior mean among evaluated points (None before the GP is fitted)."""
        if not self._skopt.models:
            return None
        gp = self._skopt.models[-1]
        X = self._transform(np.asarray(self._skopt.Xi))
        with _small_blas():
            index, mean = incumbent(gp, X)
            _, sd = gp.predict(X[index : index + 1], return_std=True)
        sign = -1.0 if self.maximize else 1.0
        return Estimate(self.space.point(self._skopt.Xi[index]), sign * mean, float(sd[0]))

    def noise_sd(self) -> float | None:
        """The GP's estimate of the evaluation noise, in objective units."""
        return noise_sd(self._skopt.models[-1]) if self._skopt.models else None

    def _transform(self, X: np.ndarray) -> np.ndarray:
        return np.asarray(self._skopt.space.transform(np.atleast_2d(X).tolist()))

    def _candidates(self, rng: np.random.Generator, gp, X_transformed: np.ndarray) -> np.ndarray:
        low, high = np.array(self.space.bounds).T
        centres = np.asarray(self._skopt.Xi)[np.argsort(gp.predict(X_transformed))[:_LOCAL_CENTRES]]
        local = (
            centres[:, None, :] + _LOCAL_SD * (high - low) * rng.standard_normal((len(centres), _LOCAL_CANDIDATES, len(low)))
        ).reshape(-1, len(low)).clip(low, high)
        return np.concatenate([self.space.sample(rng, _GLOBAL_CANDIDATES), local[self.space.feasible_mask(local)]])


@dataclass
class OptimizationRun:
    """What a finished (or resumed-to-finish) run holds: the records, in index order."""

    evaluations: list[dict]
    estimates: list[dict]
    optimizer: StrokeOptimizer
    timing_s: dict[str, float] = field(default_factory=dict)

    @property
    def best(self) -> Estimate:
        estimate = self.optimizer.best()
        if estimate is None:
            raise OptimizerError(
                f"only {len(self.evaluations)} evaluations: the GP needs {self.optimizer.n_initial_points}"
            )
        return estimate


def optimize(
    objective: Objective,
    space: SearchSpace,
    log_path: str | Path,
    *,
    iterations: int = DEFAULT_ITERATIONS,
    maximize: bool = True,
    plan: MeasurementPlan = MeasurementPlan(),
    resume: bool = False,
    n_initial_points: int = DEFAULT_INITIAL_POINTS,
    exploration_ratio: float = DEFAULT_EXPLORATION_RATIO,
    context: Mapping[str, object] | None = None,
    on_evaluation: Callable[[dict], None] | None = None,
    batch_size: int = 1,
    executor: Executor | None = None,
) -> OptimizationRun:
    """Run (or continue) `iterations` evaluations of the stroke, logging each one to log_path.

    `context` (scene name, fixed overrides...) goes into the log header, so a resume with another
    setup is refused. `on_evaluation` sees every new evaluation record (progress display).
    Evaluations are asked `batch_size` at a time (`StrokeOptimizer.ask_batch`) and run on
    `executor` (default: this process); batches start at multiples of `batch_size`, and records
    are logged in index order as soon as their predecessors are, so a resumed run re-asks the
    interrupted batch, keeps its logged part and proposes exactly what the uninterrupted run would.
    """
    if iterations < n_initial_points:
        raise OptimizerError(f"iterations = {iterations} must be >= n_initial_points = {n_initial_points}")
    if batch_size < 1:
        raise OptimizerError(f"batch size {batch_size} must be >= 1")
    header = {
        "space": space.describe(),
        "maximize": maximize,
        "measurement": plan.describe(),
        "n_initial_points": n_initial_points,
        "exploration_ratio": exploration_ratio,
        "context": dict(context or {}),
        # Only batched logs name their batch size: sequential logs written before batches existed resume.
        **({"batch_size": batch_size} if batch_size > 1 else {}),
    }
    # The first random point's run, planned and not simulated: a setup that cannot work stops here.
    preflight(objective, space.overrides(space.point(space.sample(np.random.default_rng([plan.seed, 0]), 1)[0])),
              plan.run_length_s(space.period_s))
    log = ExperimentLog.open(log_path, header, resume=resume)
    check_log(log, study_entries(space, iterations))
    optimizer = StrokeOptimizer(
        space, maximize=maximize, n_initial_points=n_initial_points,
        exploration_ratio=exploration_ratio, seed=plan.seed,
    )
    evaluations = [r for r in log.records if r["kind"] == "evaluation"]
    estimates = {r["index"]: r for r in log.records if r["kind"] == "estimate"}
    check_in_order(log)
    # A batch cut short is asked again from its start; its logged part is kept, not rerun.
    first = len(evaluations) - len(evaluations) % batch_size if len(evaluations) < iterations else len(evaluations)
    optimizer.tell_many([r["params"] for r in evaluations[:first]], [r["thrust_ratio"] for r in evaluations[:first]])
    timing = {"simulation_s": 0.0, "optimizer_s": 0.0}
    executor = executor or InlineExecutor()

    for start in range(first, iterations, batch_size):
        started = time.perf_counter()
        points = optimizer.ask_batch(min(batch_size, iterations - start))
        asked = time.perf_counter()
        logged = evaluations[start:]
        for record, point in zip(logged, points):
            if not all(math.isclose(record["params"][k], v, rel_tol=1e-9, abs_tol=1e-12) for k, v in point.items()):
                raise OptimizerError(f"{log_path}: evaluation {record['index']} is not the point this setup asks "
                                     "there; the log was written by another version or setup")
        futures = {
            executor.submit(_evaluate_point, objective, space.overrides(point), space.period_s, plan, start + j): j
            for j, point in enumerate(points) if j >= len(logged)
        }
        results: dict[int, Evaluation | str] = {}
        for future in executor.as_completed(list(futures)):
            results[futures[future]] = future.result()
            # Log in index order: a prefix of the batch is on disk as soon as it is complete.
            while len(logged) < len(points) and len(logged) in results:
                j = len(logged)
                record = _evaluation_record(start + j, points[j], results[j], space, optimizer.last_proposals[j],
                                            log_path)
                log.append(record)
                evaluations.append(record)
                logged.append(record)
                if on_evaluation is not None:
                    on_evaluation(record)
        evaluated = time.perf_counter()
        optimizer.tell_many(points, [r["thrust_ratio"] for r in logged])
        estimate = optimizer.best()
        if estimate is not None:
            index = start + len(points) - 1
            estimates[index] = {"kind": "estimate", "index": index, "params": estimate.point,
                                "thrust_ratio": estimate.value, "sd": estimate.sd}
            log.append(estimates[index])
        timing["simulation_s"] += evaluated - asked
        timing["optimizer_s"] += (asked - started) + (time.perf_counter() - evaluated)
    return OptimizationRun(evaluations, [estimates.get(i) for i in range(len(evaluations))], optimizer, timing)


def _evaluate_point(
    objective: Objective, overrides: Mapping[str, float | str], period_s: float, plan: MeasurementPlan, index: int
) -> Evaluation | str:
    """One evaluation, in whichever process the executor chose. A simulation refusing the point
    comes back as its message (our errors do not all pickle), so the driver can name the point."""
    try:
        return evaluate(objective, overrides, period_s, plan, ITERATION_STREAM, (index,))
    except FeatherstarError as exc:  # e.g. the master's energy guard refused this stroke
        return str(exc)


def _evaluation_record(
    index: int, point: dict[str, float], result: Evaluation | str, space: SearchSpace, proposal: Proposal | None,
    log_path: str | Path,
) -> dict:
    if isinstance(result, str):
        raise OptimizerError(
            f"evaluation {index} at {point} could not be simulated: {result}. The {index} evaluations before it "
            f"are in {log_path}; --resume would ask this point again, so narrow the search space (or fix the "
            "scene) first"
        )
    if not math.isfinite(result.thrust_ratio):
        raise OptimizerError(
            f"evaluation {index} at {point} gave TR = {result.thrust_ratio}: no negative thrust in "
            "the window; check the scene's thrust sign and tare"
        )
    return {
        "kind": "evaluation",
        "index": index,
        "params": point,
        "overrides": space.overrides(point),
        "thrust_ratio": result.thrust_ratio,
        "mean_thrust_N": result.mean_thrust_N,
        "sim_wall_s": result.sim_wall_s,
        "acquisition": None if proposal is None else {
            "retries": proposal.retries, "overexploiting": proposal.overexploiting,
            "sigma_f": proposal.sigma_f, "noise_sd": proposal.noise_sd,
        },
    }
