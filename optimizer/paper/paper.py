"""`featherstar paper`: rerun the paper's experiments in simulation and report them beside its claims.

    from featherstar.optimizer.paper.paper import QUICK, generate_report
    report_md = generate_report("runs/paper", quick=True)      # or resolution=Resolution(...)

Every figure of the paper that simulation can redo (Figs. 3, 5–9) is rerun at one `Resolution`
(quick: minutes; full: the paper's own budgets, hours), drawn as a PNG, and summed up in
`DIR/report.md` with a table of the paper's numbers beside the simulated ones; every number is
also in `DIR/paper.json`. Experiments are independent tasks on an `Executor` (local processes or a
Dask cluster): the optimizer studies (best and worst controller per feather, Fig. 7's strokes), the
symmetric-stroke runs, the sweep runs, and the robot runs, which start as soon as the study giving
their controller is done. A failing task is recorded and reported; it does not sink the report.
Figures: `paper_figures`; the claims table and the markdown: `paper_report`.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ...cosim.jsonable import json_safe
from ..bayes import optimize
from ..evaluation import VALIDATION_STREAM, MeasurementPlan, noise_rng
from ..executor import Executor, Progress, make_executor
from ..loadcell import LoadCell, measure
from ..objective import SceneObjective
from ..postprocess import optional
from ..space import stroke_overrides, stroke_space, symmetric_stroke
from ..study import summarize
from ..sweep import Task, run_task, tabulate
from .plan import (
    FULL,
    MORPHOLOGIES,
    PERIOD_S,
    QUICK,
    ROBOT_SAMPLE_S,
    Resolution,
    StudySpec,
    feather_overrides,
    study_specs,
    sweep_geometries,
)
from .tasklog import TaskLog

# ---- tasks: top-level functions, run in worker processes; each returns plain data ----

def _guarded(fn: Callable[..., dict], *args: Any) -> dict:
    """Exceptions become data (some of ours do not pickle, and one failure must not sink the report)."""
    started = time.perf_counter()
    try:
        out = fn(*args)
    except Exception as exc:  # noqa: BLE001 — reported in the report's failures section
        return {"error": f"{type(exc).__name__}: {exc}", "wall_s": time.perf_counter() - started, "sim_s": 0.0}
    out.setdefault("wall_s", time.perf_counter() - started)
    return out


def _plan(res: Resolution) -> MeasurementPlan:
    return MeasurementPlan(settle_periods=res.settle_periods, periods=res.periods, seed=res.seed)


def study_task(spec: StudySpec, res: Resolution) -> dict:
    objective = SceneObjective("testbed", feather_overrides(spec.family, spec.ratio))
    space = stroke_space(spec.period_s)
    plan = _plan(res)
    # The log is the worker's scratch (the task may run on another host); the result carries it all.
    with tempfile.TemporaryDirectory(prefix="featherstar-paper-") as log_dir:
        run = optimize(
            objective, space, Path(log_dir) / f"{spec.key}.jsonl", iterations=spec.iterations,
            maximize=spec.maximize, plan=plan, n_initial_points=min(res.initial_points, spec.iterations),
            context={"scene": "testbed", "overrides": feather_overrides(spec.family, spec.ratio)},
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


# ---- orchestration ----

def _robot_controller(family: str, controller: str, results: dict) -> dict | str:
    """The controller's overrides, or why it is missing."""
    if controller == "baseline":
        return stroke_overrides(symmetric_stroke(PERIOD_S))
    study = results.get(f"study:{family}-{'max' if controller == 'best' else 'min'}", {})
    if "best_overrides" not in study:
        return f"skipped: its study failed ({study.get('error', 'no result')})"
    return {k: v for k, v in study["best_overrides"].items() if k.startswith("controller.")}


def run_experiments(
    res: Resolution, out_dir: Path, *, progress: bool = True, executor: Executor | None = None, resume: bool = False
) -> tuple[dict, dict]:
    """Run every task on `executor` (default: local processes, `res.workers`), logging each result
    in DIR/tasks.jsonl as it completes; `resume` runs only the tasks that log lacks. Returns
    (results by task label, timing)."""
    specs = study_specs(res)
    geometries = [g for family in ("chordwise", "spanwise") for g in sweep_geometries(family, res.sweep_geometries)]
    sweep_tasks = [Task(i, g, c) for i, (g, c) in enumerate((g, c) for g in geometries for c in res.sweep_controllers)]
    # Run order: the long studies first (the robot waits on them), short runs last to fill the gaps;
    # the backlog is ours (the executor only ever holds one task per slot) so robot runs can jump it.
    order = sorted(specs.values(), key=lambda s: (s.family == "plain", s.validate is False, -s.period_s))
    backlog: list[tuple[str, Callable, tuple]] = [(f"study:{s.key}", study_task, (s, res)) for s in order]
    backlog += [(f"robot:{f}-baseline", robot_task, (f, "baseline", _robot_controller(f, "baseline", {}), res))
                for f in MORPHOLOGIES]
    backlog += [(f"fig5:{f}", symmetric_task, (f, res)) for f in MORPHOLOGIES]
    backlog += [(f"sweep:{t.index}", sweep_task, (t, res)) for t in sweep_tasks]
    labels = [label for label, _, _ in backlog] + [f"robot:{f}-{c}" for f in MORPHOLOGIES for c in ("best", "worst")]
    log = TaskLog(out_dir, res.describe(), labels, resume=resume)
    results: dict[str, dict] = dict(log.done)
    backlog = [item for item in backlog if item[0] not in results]
    owned = executor is None
    executor = executor or make_executor(workers=res.workers or os.cpu_count() or 1)
    started = time.perf_counter()
    try:
        with Progress(len(labels), f"paper ({res.name})", enabled=progress, initial=len(results)) as bar:
            for label in list(results):   # resumed studies whose robot runs are still to do
                _follow_up(label, results, backlog, bar, 0, res)
            pending: dict[Any, str] = {}
            while backlog or pending:
                slots = executor.slots
                while backlog and len(pending) < slots:
                    label, fn, args = backlog.pop(0)
                    pending[executor.submit(_guarded, fn, *args)] = label
                for future in executor.wait_any(pending):
                    label = pending.pop(future)
                    results[label] = result = future.result()
                    if "run_png" in result:
                        (out_dir / f"fig5_{result['family']}_run.png").write_bytes(result.pop("run_png"))
                    log.append(label, result)
                    bar.update(running=len(pending), failed="error" in result, note=label)
                    _follow_up(label, results, backlog, bar, len(pending), res)
    finally:
        if owned:
            executor.close()
    timing = {
        "wall_s": time.perf_counter() - started, "workers": executor.slots, "executor": executor.describe(),
        "tasks": len(results),
        "task_wall_s": sum(r.get("wall_s", 0.0) for r in results.values()),
        "simulated_s": sum(r.get("sim_s", 0.0) for r in results.values()),
        "cpu_count": os.cpu_count(), "planned_simulated_s": planned_simulated_s(res),
        "full_planned_simulated_s": planned_simulated_s(FULL),
    }
    return results, timing


def _follow_up(label: str, results: dict, backlog: list, bar: Progress, running: int, res: Resolution) -> None:
    """After a best or worst study: queue the robot run with its controller (first in line), or
    record why it cannot run; nothing if that robot run is already done."""
    kind, _, key = label.partition(":")
    if kind != "study" or key not in (f"{f}-{m}" for f in MORPHOLOGIES for m in ("max", "min")):
        return
    family, which = key.rsplit("-", 1)
    controller = "best" if which == "max" else "worst"
    robot_label = f"robot:{family}-{controller}"
    if robot_label in results:
        return
    overrides = _robot_controller(family, controller, results)
    if isinstance(overrides, str):
        results[robot_label] = {"error": overrides, "wall_s": 0.0, "sim_s": 0.0}
        bar.update(running=running, failed=True, note=robot_label)
    else:
        backlog.insert(0, (robot_label, robot_task, (family, controller, overrides, res)))


def planned_simulated_s(res: Resolution) -> float:
    """Simulated seconds a resolution asks for (what the run time scales with)."""
    total = 0.0
    for spec in study_specs(res).values():
        total += spec.iterations * (res.settle_periods + res.periods) * spec.period_s
        if spec.validate:
            total += 2 * (res.settle_periods + res.validation_repeats * res.validation_periods) * spec.period_s
    total += len(MORPHOLOGIES) * (res.settle_periods + res.validation_repeats * res.validation_periods) * PERIOD_S
    total += 3 * len(MORPHOLOGIES) * res.robot_periods * PERIOD_S
    geometries = sum(len(sweep_geometries(f, res.sweep_geometries)) for f in ("chordwise", "spanwise"))
    total += geometries * sum((res.sweep_settle_periods + res.sweep_periods) * c.stroke(60.0).period_s
                              for c in res.sweep_controllers)
    return total


def collect(results: dict) -> dict:
    """Regroup task results by figure (the shape of paper.json, less the claims)."""
    sweep_rows = sorted((r["row"] for k, r in results.items() if k.startswith("sweep:") and "row" in r),
                        key=lambda row: row["index"])
    return {
        "sweep": {"runs": sweep_rows, "table": tabulate(sweep_rows) if sweep_rows else []},
        "symmetric": {k[5:]: r for k, r in results.items() if k.startswith("fig5:")},
        "studies": {k[6:]: r for k, r in results.items() if k.startswith("study:")},
        "robot": {k[6:]: r for k, r in results.items() if k.startswith("robot:")},
        "failures": {k: r["error"] for k, r in results.items() if "error" in r},
    }


def generate_report(
    out_dir: str | Path, *, quick: bool, progress: bool = True, resolution: Resolution | None = None,
    executor: Executor | None = None, resume: bool = False,
) -> Path:
    """Run the experiments at `resolution` (default QUICK or FULL) on `executor` (default: local
    processes) and write DIR/report.md, the figures and DIR/paper.json; returns the report's path.
    Every finished experiment is logged in DIR/tasks.jsonl; `resume` runs only those it lacks."""
    from .figures import draw_all
    from .report import claims, write_markdown

    res = resolution or (QUICK if quick else FULL)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    started = time.time()
    results, timing = run_experiments(res, out_dir, progress=progress, executor=executor, resume=resume)
    data = collect(results)
    timing["total_wall_s"] = time.time() - started
    payload = {"resolution": res.describe(), "timing": timing, "started_unix": started, "claims": [],
               "figures": {}, **data}
    # The results first: the claims, figures and markdown after them are post-processing, whose
    # failure is a warning and costs none of the hours of experiments in paper.json.
    _write_payload(out_dir, payload)
    table = optional("the claims table", claims, data) or []
    figures = optional("the figures", draw_all, data, res, out_dir) or {}
    payload.update(claims=table, figures={k: p.name for k, p in figures.items()})
    _write_payload(out_dir, payload)
    return write_markdown(out_dir / "report.md", data, table, figures, res, timing)


def _write_payload(out_dir: Path, payload: dict) -> None:
    """paper.json: every number of the report (per-set validation details left out: kept short)."""
    short = {**payload, "studies": {key: {**study, "summary": {k: v for k, v in study["summary"].items()
                                                               if k != "validation"}} if "summary" in study else study
                                    for key, study in payload["studies"].items()}}
    (out_dir / "paper.json").write_text(json.dumps(json_safe(short, drop_arrays=True), indent=1, allow_nan=False) + "\n")
