"""The paper's online optimization on the test bed (Sec. II-D): a study whose evaluations are bench runs.

Sequential (one bench): ask a stroke, run it on the devices (`featherstar.optimizer.bench.objective`),
log it, tell it. The JSONL log (`featherstar.optimizer.log`) is the study's only state:

    evaluation   one per index 0..n-1, exactly once: the measured TR and mean thrust
    discarded    a run thrown away (deadline misses, data gaps; see bench_objective) and repeated
    fault        a device fault that paused the study (the evaluation in flight is asked again)
    estimate     the best posterior mean after each evaluation (Fig. 6)
    validation   the optimum's and the baseline's validation runs, once each

A device fault logs a `fault` record and raises `BenchFault` with the log intact; `resume=True`
replays the log and continues: a logged evaluation or validation is never run again, and the
point asked next is the one the uninterrupted study would have asked (the optimizer's randomness
is seeded by the number of points told). With a `SimPrior`, the initial design is the simulated
study's best strokes instead of random ones (see featherstar.optimizer.bench.sim_prior). With
`prior_use="discrepancy"` the initial design is the same, and after it the study's surrogate is the
simulation plus a learned discrepancy (featherstar.optimizer.bench.discrepancy): before each bench
run the stroke is simulated too, and logged as

    simulation   the simulation's TR at evaluation `index`'s stroke (once; a resume reuses it)

The reported best is what validation measured on the bench (the model's estimate is kept beside
it, never in its place), and a best that validated below the symmetric baseline is flagged.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any, Callable, Mapping

from ..acquisition import DEFAULT_EXPLORATION_RATIO
from ..bayes import DEFAULT_INITIAL_POINTS, OptimizationRun, StrokeOptimizer
from ..errors import OptimizerError
from ..evaluation import ITERATION_STREAM, MeasurementPlan, evaluate, validate
from ..log import ExperimentLog
from ..resume import Entries, check_log
from ..space import SearchSpace
from ..study import (
    BASELINE_VALIDATION_INDEX,
    BEST_VALIDATION_INDEX,
    study_summary,
    validation_overrides,
    write_study_outputs,
)
from ..study_log import check_in_order, study_entries
from .objective import DEFAULT_MAX_ATTEMPTS, BenchObjective, Retrying
from .run import BenchFault
from .discrepancy import DEFAULT_NOISE_FLOOR_TR, DiscrepancyOptimizer, SimulationModel
from .sim_prior import SimPrior

BENCH_VALIDATION_REPEATS = 10
BENCH_VALIDATION_PERIODS = 5
PRIOR_USES = ("seed", "discrepancy")


def run_bench_study(
    bench: BenchObjective,
    space: SearchSpace,
    out_dir: str | Path,
    *,
    plan: MeasurementPlan,
    iterations: int,
    maximize: bool = True,
    resume: bool = False,
    n_initial_points: int = DEFAULT_INITIAL_POINTS,
    exploration_ratio: float = DEFAULT_EXPLORATION_RATIO,
    max_attempts: int = DEFAULT_MAX_ATTEMPTS,
    validation_repeats: int = BENCH_VALIDATION_REPEATS,
    validation_periods: int = BENCH_VALIDATION_PERIODS,
    prior: SimPrior | None = None,
    prior_use: str = "seed",
    noise_floor_sd: float | None = None,
    label: str = "feather",
    compare: tuple[Mapping, ...] = (),
    on_record: Callable[[dict], None] | None = None,
) -> dict:
    """Optimize the stroke on the bench, validate the optimum and the baseline there, and write
    DIR/evaluations.jsonl, DIR/summary.json, Fig. 6 and Fig. 8 (marked as measured).

    `plan` must read the bench's thrust as recorded (no added noise). `on_record` sees every new
    log record (progress display). Raises BenchFault (study paused, resumable) on a device fault.
    `prior_use`: "seed" (the prior's best strokes are the initial design) or "discrepancy" (the
    same initial design, at most `iterations` of it; then the surrogate is the prior's simulation
    plus a learned discrepancy; each bench stroke is also simulated, by `prior.simulation()`). `noise_floor_sd` (discrepancy only): the bench's measured
    repeatability in TR, the least noise the discrepancy may assume (default
    DEFAULT_NOISE_FLOOR_TR; featherstar.optimizer.bench.discrepancy).
    """
    if prior_use not in PRIOR_USES:
        raise OptimizerError(f"prior use {prior_use!r}: valid values are {', '.join(PRIOR_USES)}")
    discrepancy = prior is not None and prior_use == "discrepancy"
    if noise_floor_sd is not None and not discrepancy:
        raise OptimizerError("noise_floor_sd applies to prior_use='discrepancy' with a prior")
    noise_floor_sd = DEFAULT_NOISE_FLOOR_TR if noise_floor_sd is None else noise_floor_sd
    if discrepancy:
        # Its model works from the first bench point; the initial design only has to give δ
        # contrasts to learn from (the discrepancy module's doc), so a short study keeps fewer.
        n_initial_points = min(n_initial_points, iterations)
    if iterations < n_initial_points:
        raise OptimizerError(f"iterations = {iterations} must be >= n_initial_points = {n_initial_points}")
    if plan.load_cell.noise_sd_N != 0:
        raise OptimizerError("a bench study reads the real load cell: its plan must add no simulated noise")
    for name, value in (("max_attempts", max_attempts), ("validation repeats", validation_repeats),
                        ("validation periods", validation_periods)):
        if value < 1:
            raise OptimizerError(f"{name} = {value} must be >= 1")
    out_dir = Path(out_dir)
    header = {
        "measured": True,
        "bench": bench.describe(),
        "space": space.describe(),
        "maximize": maximize,
        "measurement": plan.describe(),
        "n_initial_points": n_initial_points,
        "exploration_ratio": exploration_ratio,
        "validation": {"repeats": validation_repeats, "periods": validation_periods},
        "prior": None if prior is None else {**prior.describe(), "use": prior_use,
                                             **({"noise_floor_sd": noise_floor_sd} if discrepancy else {})},
    }
    log = ExperimentLog.open(out_dir / "evaluations.jsonl", header, resume=resume)
    check_log(log, bench_entries(space, iterations))
    check_in_order(log)
    study = _Study(log, on_record)
    evaluations = study.of_kind("evaluation")
    if study.of_kind("validation") and len(evaluations) < iterations:
        raise OptimizerError(f"{log.path}: the study was already validated after {len(evaluations)} evaluations; "
                             f"its best cannot change now (the reported TR is that validation's): start a new "
                             f"--out to run {iterations}")
    simulations = {r["index"]: r for r in study.of_kind("simulation")}
    if discrepancy:
        optimizer = DiscrepancyOptimizer(space, SimulationModel(space, prior.points, prior.values, seed=plan.seed),
                                         maximize=maximize, exploration_ratio=exploration_ratio, seed=plan.seed,
                                         noise_floor_sd=noise_floor_sd)
        sim_objective, sim_plan = prior.simulation()
        for r in evaluations:
            optimizer.tell_simulation(r["params"], simulations[r["index"]]["thrust_ratio"])
    else:
        optimizer = StrokeOptimizer(space, maximize=maximize, n_initial_points=n_initial_points,
                                    exploration_ratio=exploration_ratio, seed=plan.seed)
    initial = prior.initial_points(space, n_initial_points, maximize=maximize) if prior else []
    optimizer.tell_many([r["params"] for r in evaluations], [r["thrust_ratio"] for r in evaluations])
    estimates = {r["index"]: r for r in study.of_kind("estimate")}
    started = time.perf_counter()

    for index in range(len(evaluations), iterations):
        point = initial[index] if index < len(initial) else optimizer.ask()
        proposal = optimizer.last_proposal if index >= len(initial) else None
        where = {"index": index, "params": point}
        if discrepancy:
            if index not in simulations:
                simulated = evaluate(sim_objective, space.overrides(point), space.period_s, sim_plan,
                                     ITERATION_STREAM, (index,))
                simulations[index] = {"kind": "simulation", **where, "thrust_ratio": simulated.thrust_ratio,
                                      "sim_wall_s": simulated.sim_wall_s}
                study.append(simulations[index])
            elif simulations[index]["params"] != point:
                raise OptimizerError(f"{log.path}: simulation {index} is not of the point this setup asks there; "
                                     "the log was written by another version or setup")
            optimizer.tell_simulation(point, simulations[index]["thrust_ratio"])
        result = study.measure(lambda objective: evaluate(objective, space.overrides(point), space.period_s, plan,
                                                           ITERATION_STREAM, (index,)), bench, where, max_attempts)
        if not math.isfinite(result.thrust_ratio):
            raise OptimizerError(f"evaluation {index} at {point} measured TR = {result.thrust_ratio}: no negative "
                                 "thrust in the window; check the load cell's sign and tare")
        record = {"kind": "evaluation", **where, "overrides": space.overrides(point),
                  "thrust_ratio": result.thrust_ratio, "mean_thrust_N": result.mean_thrust_N,
                  "bench_wall_s": result.sim_wall_s, "from_prior": index < len(initial),
                  "acquisition": None if proposal is None else {
                      "retries": proposal.retries, "overexploiting": proposal.overexploiting,
                      "sigma_f": proposal.sigma_f, "noise_sd": proposal.noise_sd}}
        study.append(record)
        evaluations.append(record)
        optimizer.tell(point, result.thrust_ratio)
        estimate = optimizer.best()
        if estimate is not None:
            estimates[index] = {"kind": "estimate", "index": index, "params": estimate.point,
                                "thrust_ratio": estimate.value, "sd": estimate.sd}
            study.append(estimates[index])
    run = OptimizationRun(evaluations, [estimates.get(i) for i in range(len(evaluations))], optimizer,
                          {"bench_s": time.perf_counter() - started})

    validation_started = time.perf_counter()
    validations = {r["controller"]: r for r in study.of_kind("validation")}
    for controller, overrides, index in zip(("best", "baseline"), validation_overrides(space, run.best.point),
                                            (BEST_VALIDATION_INDEX, BASELINE_VALIDATION_INDEX)):
        if controller in validations:
            continue
        result = study.measure(lambda objective: validate(objective, overrides, space.period_s, plan, index,
                                                          repeats=validation_repeats, periods=validation_periods),
                               bench, {"validation": controller, "overrides": overrides}, max_attempts)
        validations[controller] = {"kind": "validation", "controller": controller, "overrides": overrides,
                                   **result.as_dict(), "bench_wall_s": result.sim_wall_s}
        study.append(validations[controller])
    summary = study_summary(space, run, validations["best"], validations["baseline"], maximize=maximize, plan=plan,
                            repeats=validation_repeats, periods=validation_periods,
                            validation_s=time.perf_counter() - validation_started,
                            validation_simulation_s=0.0)
    summary.update(label=label, measured=True, bench=bench.describe(), **validated_best(summary, maximize),
                   prior=None if prior is None else {
                       **prior.describe(), "use": prior_use,
                       **({"model": optimizer.describe(), "simulations": len(simulations),
                           "simulation_wall_s": sum(r["sim_wall_s"] for r in simulations.values())}
                          if discrepancy else {})},
                   discarded_runs=len(study.of_kind("discarded")), faults=len(study.of_kind("fault")))
    write_study_outputs(out_dir, run, summary, label=label, compare=compare, measured=True)
    return summary


def validated_best(summary: Mapping, maximize: bool) -> dict:
    """What a bench study reports as its best: the TR validation measured (summary's
    "thrust_ratio"), how far the model's estimate was above it, and whether it validated below the
    symmetric baseline (`below_baseline`, with a warning line: the study found nothing better than
    the stroke it started from, or its estimate was fooled by noise or a biased prior)."""
    measured, baseline = summary["thrust_ratio"], summary["baseline_thrust_ratio"]
    below = measured < baseline if maximize else measured > baseline
    warnings = []
    if below:
        warnings.append(f"the study's best stroke validated at TR {measured:.3f} ± {summary['thrust_ratio_sd']:.3f}, "
                        f"{'below' if maximize else 'above'} the symmetric baseline's {baseline:.3f} ± "
                        f"{summary['baseline_thrust_ratio_sd']:.3f} (its model had estimated "
                        f"{summary['estimated_thrust_ratio']:.3f}): the baseline is the better stroke measured")
    return {"reported_thrust_ratio": measured, "reported": "validation",
            "estimate_minus_validated": summary["estimated_thrust_ratio"] - measured,
            "below_baseline": below, "warnings": warnings}


def bench_entries(space: SearchSpace, iterations: int) -> list[Entries]:
    """What a bench study's log holds: the optimizer's evaluations and estimates, the bench's
    events (discarded runs, faults: they may repeat) and one validation per controller."""
    return [
        *study_entries(space, iterations, extra={"bench_wall_s": "number", "from_prior": "bool"}),
        Entries("discarded", {"reasons": "list"}),
        Entries("fault", {"message": "str"}),
        Entries("simulation", {"index": "int", "params": "dict", "thrust_ratio": "number", "sim_wall_s": "number"},
                key="index", planned=lambda index: {} if 0 <= index < iterations else None,
                plan=f"indices 0..{iterations - 1}"),
        Entries("validation", {"controller": "str", "thrust_ratio": "number", "thrust_ratio_sd": "number",
                               "mean_thrust_N": "number", "mean_thrust_sd_N": "number"}, key="controller",
                planned=lambda controller: {} if controller in ("best", "baseline") else None,
                plan="one validation of the best and one of the baseline"),
    ]


class _Study:
    """The log plus the bookkeeping of discards and faults around one bench measurement."""

    def __init__(self, log: ExperimentLog, on_record: Callable[[dict], None] | None) -> None:
        self.log = log
        self.on_record = on_record

    def of_kind(self, kind: str) -> list[dict]:
        return [r for r in self.log.records if r["kind"] == kind]

    def append(self, record: dict) -> None:
        self.log.append(record)
        if self.on_record is not None:
            self.on_record(record)

    def measure(self, measurement: Callable[[Any], Any], bench: BenchObjective, where: dict,
                max_attempts: int) -> Any:
        """Run `measurement(objective)` on the bench, logging each discarded run; on a device
        fault, log it and pause the study."""
        def discarded(reasons: list[str], summary: Mapping[str, Any]) -> None:
            self.append({"kind": "discarded", **where, "reasons": reasons,
                         "deadline_misses": summary.get("deadline_misses"), "gaps": summary.get("gaps"),
                         "worst_lateness_s": summary.get("worst_lateness_s")})

        try:
            return measurement(Retrying(bench, discarded, max_attempts))
        except BenchFault as fault:
            self.append({"kind": "fault", **where, "message": str(fault), "block": fault.block})
            done = len(self.of_kind("evaluation"))
            raise BenchFault(f"study paused: {fault}. The {done} evaluations so far are in {self.log.path}; "
                             "fix the bench and rerun with --resume", block=fault.block, t_s=fault.t_s) from None
