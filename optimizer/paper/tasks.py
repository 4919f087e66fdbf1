"""The report's experiments as tasks: top-level functions run in worker processes (local or on a
Dask cluster), each taking plain data and returning plain data (`featherstar.optimizer.paper.paper`
schedules them; `family` reruns them under the model family)."""
from __future__ import annotations

import dataclasses
import math
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from ..bayes import optimize
from ..evaluation import VALIDATION_STREAM, MeasurementPlan, noise_rng
from ..loadcell import LoadCell, measure
from ..objective import SceneObjective
from ..space import stroke_overrides, stroke_space, symmetric_stroke
from ..study import summarize
from ..sweep import Task, run_task
from .plan import MORPHOLOGIES, PERIOD_S, ROBOT_SAMPLE_S, Resolution, StudySpec, feather_overrides


def guarded(fn: Callable[..., dict], *args: Any) -> dict:
    """Exceptions become data (some of ours do not pickle, and one failure must not sink the report)."""
    started = time.perf_counter()
    try:
        out = fn(*args)
    except Exception as exc:  # noqa: BLE001 — reported in the report's failures section
        return {"error": f"{type(exc).__name__}: {exc}", "wall_s": time.perf_counter() - started, "sim_s": 0.0}
    out.setdefault("wall_s", time.perf_counter() - started)
    return out


def measurement_plan(res: Resolution) -> MeasurementPlan:
    """The test bed's measurement at `res` (settling, periods per evaluation, noise seed)."""
    return MeasurementPlan(settle_periods=res.settle_periods, periods=res.periods, seed=res.seed)


def study_task(spec: StudySpec, res: Resolution, model: Mapping[str, Any] | None = None) -> dict:
    """One stroke optimization (and, with `spec.validate`, its validation); `model`: feather
    overrides on top of the default model (a model-family member's)."""
    feather = {**feather_overrides(spec.family, spec.ratio), **(model or {})}
    objective = SceneObjective("testbed", feather)
    space = stroke_space(spec.period_s)
    plan = measurement_plan(res)
    # The log is the worker's scratch (the task may run on another host); the result carries it all.
    with tempfile.TemporaryDirectory(prefix="featherstar-paper-") as log_dir:
        run = optimize(
            objective, space, Path(log_dir) / f"{spec.key}.jsonl", iterations=spec.iterations,
            maximize=spec.maximize, plan=plan, n_initial_points=min(res.initial_points, spec.iterations),
            context={"scene": "testbed", "overrides": feather},
        )
    best = run.best
    stroke = space.stroke(best.point)
    out = {
        "spec": dataclasses.asdict(spec),
        "evaluations": [{"thrust_ratio": e["thrust_ratio"], "mean_thrust_N": e["mean_thrust_N"],
                         "params": e["params"]} for e in run.evaluations],
        "estimates": [None if e is None else {"thrust_ratio": e["thrust_ratio"], "params": e["params"]}
                      for e in run.estimates],
        "names": list(space.names),
        "best_point": best.point, "estimated_thrust_ratio": best.value, "estimated_thrust_ratio_sd": best.sd,
        "best_overrides": space.overrides(best.point),
        "stroke": dataclasses.asdict(stroke),
        "sim_s": len(run.evaluations) * (plan.settle_periods + plan.periods) * spec.period_s,
    }
    if spec.validate:
        summary = summarize(objective, space, run, maximize=spec.maximize, plan=plan,
                            repeats=res.validation_repeats, periods=res.validation_periods)
        out["summary"] = summary
        out["sim_s"] += 2 * (plan.settle_periods + res.validation_repeats * res.validation_periods) * spec.period_s
    return out


def symmetric_task(family: str, res: Resolution) -> dict:
    """Fig. 5: one long run under the symmetric stroke, read like the bench (sets of periods); the
    run's own figure comes back as PNG bytes (the task may run on another host)."""
    from ...cosim import run_scene
    from ...cosim.swimmer.report import plot_run

    settle, sets, per = res.settle_periods, res.validation_repeats, res.validation_periods
    load_cell = LoadCell()
    t_end = (settle + sets * per) * PERIOD_S + 2.0 / load_cell.sample_rate_hz
    result = run_scene("testbed", {**feather_overrides(family), **stroke_overrides(symmetric_stroke(PERIOD_S)),
                                   "master.t_end_s": t_end, "metrics.settle_periods": settle})
    t, thrust = result.time, result["feather.thrust_N"]
    rng = noise_rng(res.seed, VALIDATION_STREAM, (100 + MORPHOLOGIES.index(family),))
    sets_measured = measure(t, thrust, PERIOD_S, load_cell, rng, settle_periods=settle, periods=per, windows=sets)
    with tempfile.TemporaryDirectory(prefix="featherstar-paper-") as tmp:
        plot_run(result, Path(tmp) / "run.png")
        run_png = (Path(tmp) / "run.png").read_bytes()
    window = t >= settle * PERIOD_S
    fold = result.signals.get("feather.flap_angle_rad")
    ratios = np.array([m.thrust_ratio for m in sets_measured])
    thrusts = np.array([m.mean_thrust_N for m in sets_measured])
    return {
        "family": family, "time_s": t, "thrust_N": thrust, "angle_rad": result["servo.angle_rad"],
        "thrust_ratio": float(ratios.mean()), "thrust_ratio_sd": float(ratios.std(ddof=1)) if sets > 1 else 0.0,
        "mean_thrust_N": float(thrusts.mean()), "mean_thrust_sd_N": float(thrusts.std(ddof=1)) if sets > 1 else 0.0,
        "sets": [{"thrust_ratio": m.thrust_ratio, "mean_thrust_N": m.mean_thrust_N} for m in sets_measured],
        "noise_free_thrust_ratio": result.summary.get("thrust_ratio"),
        "peak_thrust_N": [float(thrust[window].min()), float(thrust[window].max())],
        "max_fold_deg": None if fold is None or family == "plain" else float(np.degrees(fold[window].max())),
        "sim_s": t_end, "run_png": run_png,
    }


def sweep_task(task: Task, res: Resolution) -> dict:
    plan = MeasurementPlan(load_cell=LoadCell(noise_sd_N=0.0), settle_periods=res.sweep_settle_periods,
                           periods=res.sweep_periods, seed=res.seed)
    row = run_task(SceneObjective("kinematic"), task, plan, 60.0)
    period = task.controller.stroke(60.0).period_s
    return {"row": row, "sim_s": (res.sweep_settle_periods + res.sweep_periods) * period}


def robot_task(family: str, controller: str, overrides: dict, res: Resolution) -> dict:
    """Fig. 9: the two-feather robot on its rail with a controller found on the test bed."""
    from ...cosim import run_scene

    result = run_scene("robot", {**feather_overrides(family), **overrides, "master.periods": res.robot_periods,
                                 "metrics.settle_periods": res.robot_settle_periods})
    t = result.time
    keep = np.searchsorted(t, np.arange(t[0], t[-1], ROBOT_SAMPLE_S))
    s = result.summary
    return {
        "family": family, "controller": controller, "controller_overrides": overrides,
        "time_s": t[keep], "position_m": result["robot.body_position_m"][keep],
        "speed_m_s": result["robot.body_speed_m_s"][keep],
        "mean_speed_m_s": s.get("mean_speed_m_s", math.nan), "thrust_ratio": s.get("thrust_ratio", math.nan),
        "mean_thrust_N": s.get("mean_thrust_N", math.nan), "sim_s": float(t[-1] - t[0]),
    }


def robot_controller(family: str, controller: str, results: dict) -> dict | str:
    """The controller's overrides, or why it is missing."""
    if controller == "baseline":
        return stroke_overrides(symmetric_stroke(PERIOD_S))
    study = results.get(f"study:{family}-{'max' if controller == 'best' else 'min'}", {})
    if "best_overrides" not in study:
        return f"skipped: its study failed ({study.get('error', 'no result')})"
    return {k: v for k, v in study["best_overrides"].items() if k.startswith("controller.")}
