"""The paper's controller study for one feather: optimize, validate the optimum and the baseline.

1. Bayesian optimization of the stroke (`featherstar.optimizer.bayes.optimize`, logged, resumable);
2. the reported optimum is the evaluated point with the best posterior mean;
3. it and the symmetric baseline are validated like the paper's Sec. III-D: 10 sets of 5 cycles;
4. `summary.json`, Fig. 6 (progress) and Fig. 8 (validation) go next to the log.
"""
from __future__ import annotations

import functools
import json
import math
import time
from pathlib import Path
from typing import Callable, Mapping

from .bayes import DEFAULT_INITIAL_POINTS, DEFAULT_ITERATIONS, OptimizationRun, optimize
from .acquisition import DEFAULT_EXPLORATION_RATIO
from .evaluation import MeasurementPlan, validate
from .executor import Executor, InlineExecutor
from .figures import progress_figure, validation_figure
from .log import dumps
from .objective import Objective
from .postprocess import optional
from .space import LOG_HOLD_MOVE, LOG_HOLD_UP_DOWN, LOG_UP_DOWN, SearchSpace, stroke_overrides, symmetric_stroke

VALIDATION_REPEATS = 10
VALIDATION_PERIODS = 5
# Validation runs get their own noise indices: the optimum and the baseline never share noise.
BEST_VALIDATION_INDEX, BASELINE_VALIDATION_INDEX = (0,), (1,)


def baseline_point(space: SearchSpace, like: Mapping[str, float]) -> dict[str, float]:
    """The symmetric stroke's coordinates, with `like`'s values for any extra variables."""
    point = dict(like)
    point.update({LOG_UP_DOWN: 0.0, LOG_HOLD_UP_DOWN: 0.0, LOG_HOLD_MOVE: math.log10(2.0)})
    return point


def baseline_outside_box(space: SearchSpace, like: Mapping[str, float] | None = None) -> str | None:
    """What to tell a user whose search box excludes the baseline (the paper's symmetric stroke),
    or None when the box holds it: the optimizer never proposes the baseline, so a short study can
    end below it. `like` gives the extra, non-stroke variables (default: the box's centre)."""
    like = like if like is not None else {v.name: 0.5 * (v.low + v.high) for v in space.variables}
    problems = space.violations(baseline_point(space, like))
    if not problems:
        return None
    stroke = symmetric_stroke(space.period_s, space.amplitude_deg)
    min_ramp_s = space.servo.min_ramp_s(space.amplitude_deg)
    servo = (f"; the servo's box wants ramps >= {min_ramp_s:.3f} s for {space.amplitude_deg:g}° at "
             f"{space.servo.max_rate_rad_s:g} rad/s (--servo-rate)" if stroke.t_up_s < min_ramp_s else "")
    return (f"the baseline lies outside the search box: {'; '.join(problems)} (the baseline is the symmetric stroke, "
            f"ramps {stroke.t_up_s:g} s, holds {stroke.t_hold_up_s:g} s{servo}); it is validated beside the optimum, "
            "but the optimizer cannot propose it, so a short study may end below it")


def summarize(
    objective: Objective,
    space: SearchSpace,
    run: OptimizationRun,
    *,
    maximize: bool,
    plan: MeasurementPlan,
    repeats: int = VALIDATION_REPEATS,
    periods: int = VALIDATION_PERIODS,
    executor: Executor | None = None,
) -> dict:
    """Validate the optimum and the baseline (side by side on `executor`, default this process);
    the dict written as summary.json."""
    best_overrides, baseline_overrides = validation_overrides(space, run.best.point)
    started = time.perf_counter()
    executor = executor or InlineExecutor()
    run_validation = functools.partial(validate, repeats=repeats, periods=periods)
    validated, baseline = [
        future.result() for future in [
            executor.submit(run_validation, objective, overrides, space.period_s, plan, index)
            for overrides, index in ((best_overrides, BEST_VALIDATION_INDEX), (baseline_overrides, BASELINE_VALIDATION_INDEX))
        ]
    ]
    return study_summary(space, run, validated.as_dict(), baseline.as_dict(), maximize=maximize, plan=plan,
                         repeats=repeats, periods=periods, validation_s=time.perf_counter() - started,
                         validation_simulation_s=validated.sim_wall_s + baseline.sim_wall_s)


def validation_overrides(space: SearchSpace, best_point: Mapping[str, float]) -> tuple[dict, dict]:
    """Scene overrides of the optimum and of the symmetric baseline (with the optimum's extra,
    non-stroke variables)."""
    best_overrides = space.overrides(best_point)
    extras = {k: v for k, v in best_overrides.items() if not k.startswith("controller.")}
    return best_overrides, {**stroke_overrides(symmetric_stroke(space.period_s, space.amplitude_deg)), **extras}


def study_summary(
    space: SearchSpace,
    run: OptimizationRun,
    validated: Mapping,
    baseline: Mapping,
    *,
    maximize: bool,
    plan: MeasurementPlan,
    repeats: int,
    periods: int,
    validation_s: float,
    validation_simulation_s: float,
) -> dict:
    """The summary.json dict from a finished run and the two validations (`Validation.as_dict()`)."""
    best = run.best
    best_overrides, baseline_overrides = validation_overrides(space, best.point)
    return {
        "objective": "max" if maximize else "min",
        "iterations": len(run.evaluations),
        "best_params": best.point,
        "best_overrides": best_overrides,
        "estimated_thrust_ratio": best.value,
        "estimated_thrust_ratio_sd": best.sd,
        "estimated_noise_sd": run.optimizer.noise_sd(),
        "thrust_ratio": validated["thrust_ratio"],
        "thrust_ratio_sd": validated["thrust_ratio_sd"],
        "mean_thrust_N": validated["mean_thrust_N"],
        "mean_thrust_sd_N": validated["mean_thrust_sd_N"],
        "baseline_overrides": baseline_overrides,
        "baseline_thrust_ratio": baseline["thrust_ratio"],
        "baseline_thrust_ratio_sd": baseline["thrust_ratio_sd"],
        "baseline_mean_thrust_N": baseline["mean_thrust_N"],
        "baseline_mean_thrust_sd_N": baseline["mean_thrust_sd_N"],
        "baseline_servo_violations": space.violations(baseline_point(space, best.point)),
        "baseline_outside_search_box": baseline_outside_box(space, best.point),
        "validation": {"repeats": repeats, "periods": periods, "best": dict(validated), "baseline": dict(baseline)},
        "measurement": plan.describe(),
        "space": space.describe(),
        "timing_s": {
            **run.timing_s,
            "validation_s": validation_s,
            "validation_simulation_s": validation_simulation_s,
        },
    }


def write_study_outputs(
    out_dir: Path, run: OptimizationRun, summary: dict, *, label: str, compare: tuple[Mapping, ...] = (),
    measured: bool = False,
) -> None:
    """Fig. 6, Fig. 8 and summary.json; `measured` marks a bench study in the figures' titles."""
    (out_dir / "summary.json").write_text(json.dumps(json.loads(dumps(summary)), indent=2) + "\n")
    # Then the figures: optional, a failure there is a warning (summary.json is already written).
    source = "measured on the bench" if measured else "simulated"
    optional("fig6_progress.png", progress_figure, run.evaluations, run.estimates, run.optimizer.space.names,
             out_dir / "fig6_progress.png", title=f"Fig. 6: optimizer progress, {label} ({source})")
    rows = validation_rows(summary, label)
    for other in compare:
        rows = (optional(f"comparison with {other.get('label', '?')} in Fig. 8", validation_rows, other,
                         other.get("label", "?")) or []) + rows
    optional("fig8_validation.png", validation_figure, rows, out_dir / "fig8_validation.png",
             title=f"Fig. 8: validation, {source}")


SUMMARY_KEYS = ("objective", "thrust_ratio", "thrust_ratio_sd", "mean_thrust_N", "mean_thrust_sd_N",
                "baseline_thrust_ratio", "baseline_thrust_ratio_sd", "baseline_mean_thrust_N",
                "baseline_mean_thrust_sd_N")


def validation_rows(summary: Mapping, morphology: str) -> list[dict]:
    """Fig. 8 rows (optimum and baseline) from a summary (one with every SUMMARY_KEYS key)."""
    controller = "best" if summary["objective"] == "max" else "worst"
    return [
        {"morphology": morphology, "controller": controller, "thrust_ratio": summary["thrust_ratio"],
         "thrust_ratio_sd": summary["thrust_ratio_sd"], "mean_thrust_N": summary["mean_thrust_N"],
         "mean_thrust_sd_N": summary["mean_thrust_sd_N"]},
        {"morphology": morphology, "controller": "baseline", "thrust_ratio": summary["baseline_thrust_ratio"],
         "thrust_ratio_sd": summary["baseline_thrust_ratio_sd"], "mean_thrust_N": summary["baseline_mean_thrust_N"],
         "mean_thrust_sd_N": summary["baseline_mean_thrust_sd_N"]},
    ]


def run_study(
    objective: Objective,
    space: SearchSpace,
    out_dir: str | Path,
    *,
    maximize: bool = True,
    iterations: int = DEFAULT_ITERATIONS,
    plan: MeasurementPlan = MeasurementPlan(),
    resume: bool = False,
    context: Mapping[str, object] | None = None,
    n_initial_points: int = DEFAULT_INITIAL_POINTS,
    exploration_ratio: float = DEFAULT_EXPLORATION_RATIO,
    label: str = "feather",
    compare: tuple[Mapping, ...] = (),
    on_evaluation: Callable[[dict], None] | None = None,
    batch_size: int = 1,
    executor: Executor | None = None,
) -> dict:
    """Optimize, validate and write DIR/evaluations.jsonl, DIR/summary.json and the two figures.

    `compare` holds earlier summaries (with a "label") to draw in the same Fig. 8. Evaluations
    run `batch_size` at a time on `executor` (see `featherstar.optimizer.bayes.optimize`).
    """
    out_dir = Path(out_dir)
    started = time.perf_counter()
    run = optimize(
        objective, space, out_dir / "evaluations.jsonl", iterations=iterations, maximize=maximize, plan=plan,
        resume=resume, n_initial_points=n_initial_points, exploration_ratio=exploration_ratio,
        context=context, on_evaluation=on_evaluation, batch_size=batch_size, executor=executor,
    )
    summary = summarize(objective, space, run, maximize=maximize, plan=plan, executor=executor)
    summary["label"] = label
    summary["context"] = dict(context or {})
    summary["measured"] = False
    summary["timing_s"]["total_s"] = time.perf_counter() - started
    write_study_outputs(out_dir, run, summary, label=label, compare=compare)
    return summary
