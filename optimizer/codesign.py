"""Beyond the paper: morphology and stroke optimized in one search, against the two-stage approach.

Joint: one Bayesian optimization over (WR or LR) × the three stroke log-ratios.
Two-stage (the paper's workflow, at the same number of experiments): stage 1 measures evenly spaced
morphologies under the symmetric stroke (as the paper compared feathers in Sec. III-A) and keeps
the one with the highest TR; stage 2 optimizes the stroke for it with the remaining budget.
Both optima are then validated the same way (10 sets of 5 cycles), so the comparison is fair in
experiments spent and in how the result is measured.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..fmu_src.errors import FeatherstarError
from .bayes import DEFAULT_INITIAL_POINTS
from .errors import OptimizerError
from .evaluation import ITERATION_STREAM, MeasurementPlan, evaluate
from .executor import Executor, InlineExecutor
from .log import ExperimentLog, dumps
from .objective import Objective, Overrides, Trace, WithOverrides, preflight
from .resume import Entries, check_log
from .space import ServoLimits, Variable, stroke_overrides, stroke_space, symmetric_stroke
from .study import run_study
from .sweep import L_ROOT_M, W_SPINE_M, Geometry

# Morphology ranges of the paper's sweeps: w 15–120 mm over the spine; l 60–180 mm over l_root.
MORPHOLOGY_VARIABLES = {
    "chordwise": Variable("feather.width_ratio", 0.015 / W_SPINE_M, 0.120 / W_SPINE_M, "1", "WR = w / w_spine"),
    "spanwise": Variable("feather.length_ratio", 0.060 / L_ROOT_M, 0.180 / L_ROOT_M, "1", "LR = l / l_root"),
}
# Stage-1 experiments get their own noise indices, apart from the optimizer's iterations.
_STAGE1_INDEX_OFFSET = 1_000_000


@dataclass(frozen=True)
class MorphologyObjective:
    """Completes a morphology ratio into the full geometry overrides the sweep uses (chordwise at
    l = 120 mm, spanwise at w = 120 mm), then runs the wrapped objective."""

    objective: Objective
    family: str

    def _complete(self, overrides: Overrides) -> dict:
        ratio = float(overrides[MORPHOLOGY_VARIABLES[self.family].name])
        if self.family == "chordwise":
            geometry = Geometry("chordwise", ratio * W_SPINE_M, 0.120)
        else:
            geometry = Geometry("spanwise", 0.120, ratio * L_ROOT_M)
        return {**overrides, **geometry.overrides()}

    def check(self, overrides: Overrides, duration_s: float) -> None:
        preflight(self.objective, self._complete(overrides), duration_s)

    def __call__(self, overrides: Overrides, duration_s: float) -> Trace:
        return self.objective(self._complete(overrides), duration_s)


def codesign(
    objective: Objective,
    family: str,
    out_dir: str | Path,
    *,
    period_s: float = 1.5,
    budget: int = 30,
    stage1_experiments: int | None = None,
    plan: MeasurementPlan = MeasurementPlan(),
    amplitude_deg: float = 60.0,
    servo: ServoLimits = ServoLimits(),
    resume: bool = False,
    context: dict | None = None,
    batch_size: int = 1,
    executor: Executor | None = None,
) -> dict:
    """Run both approaches with `budget` experiments each; write and return DIR/codesign.json.

    Experiments run on `executor` (default: this process): the optimizer's `batch_size` at a
    time, stage 1's all at once.
    """
    if family not in MORPHOLOGY_VARIABLES:
        raise OptimizerError(f"unknown morphology family {family!r}; known: {sorted(MORPHOLOGY_VARIABLES)}")
    stage1 = budget // 3 if stage1_experiments is None else stage1_experiments
    if not 2 <= stage1 <= budget - DEFAULT_INITIAL_POINTS:
        raise OptimizerError(
            f"stage 1 needs 2..{budget - DEFAULT_INITIAL_POINTS} of the {budget} experiments, got {stage1}"
        )
    out_dir = Path(out_dir)
    variable = MORPHOLOGY_VARIABLES[family]
    wrapped = MorphologyObjective(objective, family)
    context = {**(context or {}), "family": family, "budget": budget}

    joint = run_study(
        wrapped, stroke_space(period_s, amplitude_deg=amplitude_deg, servo=servo, extra=[variable]),
        out_dir / "joint", iterations=budget, plan=plan, resume=resume,
        context={**context, "approach": "joint"}, label=f"{family} joint", batch_size=batch_size, executor=executor,
    )

    stage1_rows = _stage1(wrapped, variable, stage1, out_dir / "stage1.jsonl", period_s=period_s, plan=plan,
                          amplitude_deg=amplitude_deg, resume=resume, context=context,
                          executor=executor or InlineExecutor())
    chosen = max(stage1_rows, key=lambda r: r["thrust_ratio"])["ratio"]
    fixed = WithOverrides(wrapped, {variable.name: chosen})
    two_stage = run_study(
        fixed, stroke_space(period_s, amplitude_deg=amplitude_deg, servo=servo),
        out_dir / "two_stage", iterations=budget - stage1, plan=plan, resume=resume,
        context={**context, "approach": "two-stage", "ratio": chosen}, label=f"{family} two-stage",
        batch_size=batch_size, executor=executor,
    )
    report = {
        "family": family,
        "budget": budget,
        "joint": {"ratio": joint["best_params"][variable.name], "thrust_ratio": joint["thrust_ratio"],
                  "thrust_ratio_sd": joint["thrust_ratio_sd"], "mean_thrust_N": joint["mean_thrust_N"],
                  "best_params": joint["best_params"]},
        "two_stage": {"ratio": chosen, "stage1": stage1_rows, "thrust_ratio": two_stage["thrust_ratio"],
                      "thrust_ratio_sd": two_stage["thrust_ratio_sd"], "mean_thrust_N": two_stage["mean_thrust_N"],
                      "best_params": two_stage["best_params"]},
    }
    (out_dir / "codesign.json").write_text(json.dumps(json.loads(dumps(report)), indent=2) + "\n")
    return report



def _stage1(objective: Objective, variable: Variable, count: int, log_path: Path, *, period_s: float,
            plan: MeasurementPlan, amplitude_deg: float, resume: bool, context: dict, executor: Executor) -> list[dict]:
    """Stage 1: `count` evenly spaced morphologies under the symmetric stroke, each logged as it
    completes (so a resumed co-design runs only the missing ones), in ratio order."""
    symmetric = stroke_overrides(symmetric_stroke(period_s, amplitude_deg))
    ratios = [float(r) for r in np.linspace(variable.low, variable.high, count)]
    header = {"stage1": {"variable": variable.name, "ratios": ratios, "period_s": period_s,
                         "amplitude_deg": amplitude_deg}, "measurement": plan.describe(), "context": context}
    log = ExperimentLog.open(log_path, header, resume=resume)
    check_log(log, [Entries("stage1", {"k": "int", "ratio": "number", "thrust_ratio": "number",
                                       "mean_thrust_N": "number"}, key="k",
                            planned=lambda k: {"ratio": ratios[k]} if isinstance(k, int) and 0 <= k < count else None,
                            plan=f"morphologies 0..{count - 1}")])
    rows = {r["k"]: r for r in log.records}
    futures = {executor.submit(_stage1_run, objective, {**symmetric, variable.name: ratio}, period_s, plan, k): k
               for k, ratio in enumerate(ratios) if k not in rows}
    for future in executor.as_completed(list(futures)):
        k = futures[future]
        result = future.result()
        if isinstance(result, str):
            raise OptimizerError(f"stage 1 at {variable.name} = {ratios[k]:g} could not be simulated: {result}; "
                                 f"the finished ones are in {log_path}")
        rows[k] = {"kind": "stage1", "k": k, "ratio": ratios[k], "thrust_ratio": result.thrust_ratio,
                   "mean_thrust_N": result.mean_thrust_N}
        log.append(rows[k])
    return [{key: float(rows[k][key]) for key in ("ratio", "thrust_ratio", "mean_thrust_N")} for k in range(count)]


def _stage1_run(objective: Objective, overrides: dict, period_s: float, plan: MeasurementPlan, k: int):
    """One stage-1 experiment, in a worker; a simulation refusing it comes back as its message
    (not all of our errors pickle)."""
    try:
        return evaluate(objective, overrides, period_s, plan, ITERATION_STREAM, (_STAGE1_INDEX_OFFSET + k,))
    except FeatherstarError as exc:
        return str(exc)
