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
Figures: `paper_figures`; the claims table and the markdown: `paper_report`. Every claim is also
judged under the feather's model family (`res.family`): `family` plans those runs as more tasks of
the same log, `robustness` gives each claim its range and whether the model decides it. The
experiments themselves are in `tasks`.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any, Callable

from ...cosim.jsonable import json_safe
from ..executor import Executor, Progress, make_executor
from ..postprocess import optional
from ..sweep import Task, tabulate
from . import family as model_family
from .plan import FULL, MORPHOLOGIES, PERIOD_S, QUICK, Resolution, study_specs, sweep_geometries
from .tasklog import TaskLog
from .tasks import guarded, robot_controller, robot_task, study_task, sweep_task, symmetric_task

__all__ = ["FULL", "QUICK", "collect", "generate_report", "run_experiments", "study_specs", "sweep_geometries"]

# ---- orchestration ----

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
    backlog += [(f"robot:{f}-baseline", robot_task, (f, "baseline", robot_controller(f, "baseline", {}), res))
                for f in MORPHOLOGIES]
    backlog += [(f"fig5:{f}", symmetric_task, (f, res)) for f in MORPHOLOGIES]
    backlog += model_family.backlog(res)   # the model family's runs that wait on no study
    backlog += [(f"sweep:{t.index}", sweep_task, (t, res)) for t in sweep_tasks]
    labels = [label for label, _, _ in backlog] + [f"robot:{f}-{c}" for f in MORPHOLOGIES for c in ("best", "worst")]
    labels += sorted(set(model_family.labels(res)) - set(labels))
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
                    pending[executor.submit(guarded, fn, *args)] = label
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
    """After a best or worst study: queue the robot run with its controller and the model family's
    runs of its optimum (first in line), or record why they cannot run; nothing for those done."""
    items, failed = model_family.follow_ups(label, results, res)
    backlog[:0] = items
    for failed_label, result in failed.items():
        results[failed_label] = result
        bar.update(running=running, failed=True, note=failed_label)
    kind, _, key = label.partition(":")
    if kind != "study" or key not in (f"{f}-{m}" for f in MORPHOLOGIES for m in ("max", "min")):
        return
    family, which = key.rsplit("-", 1)
    controller = "best" if which == "max" else "worst"
    robot_label = f"robot:{family}-{controller}"
    if robot_label in results:
        return
    overrides = robot_controller(family, controller, results)
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
    return total + model_family.planned_simulated_s(res)


def collect(results: dict) -> dict:
    """Regroup task results by figure (the shape of paper.json, less the claims)."""
    sweep_rows = sorted((r["row"] for k, r in results.items() if k.startswith("sweep:") and "row" in r),
                        key=lambda row: row["index"])
    return {
        "sweep": {"runs": sweep_rows, "table": tabulate(sweep_rows) if sweep_rows else []},
        "symmetric": {k[5:]: r for k, r in results.items() if k.startswith("fig5:")},
        "studies": {k[6:]: r for k, r in results.items() if k.startswith("study:")},
        "robot": {k[6:]: r for k, r in results.items() if k.startswith("robot:")},
        "family": model_family.collect(results),
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
    from .robustness import family_table

    res = resolution or (QUICK if quick else FULL)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    started = time.time()
    results, timing = run_experiments(res, out_dir, progress=progress, executor=executor, resume=resume)
    data = collect(results)
    timing["total_wall_s"] = time.time() - started
    payload = {"resolution": res.describe(), "family_members": model_family.describe(res), "timing": timing,
               "started_unix": started, "claims": [],
               "figures": {}, **data}
    # The results first: the claims, figures and markdown after them are post-processing, whose
    # failure is a warning and costs none of the hours of experiments in paper.json.
    _write_payload(out_dir, payload)
    table = optional("the claims table", claims, data) or []
    table = optional("the model family's ranges", family_table, data, table, res, claims) or table
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
