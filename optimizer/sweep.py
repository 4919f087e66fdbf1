"""Morphology sweeps as in the paper's Fig. 3: every geometry × a grid of controllers, in parallel.

Chordwise flaps: w = 15–120 mm in 5 mm steps at l = 120 mm, WR = w / w_spine (w_spine = 10 mm).
Spanwise flaps: l = 60–180 mm in 10 mm steps at w = 120 mm, LR = l / l_root. The paper gives no
l_root for the sweep; its tested spanwise feather is LR 2.0 at l = 115 mm, so l_root = 57.5 mm,
and the sweep spans LR 1.04–3.13 (LR 1, no outer part, is not a feather with a flap).

Controllers: t_up ∈ {0.1, 0.5}, t_down ∈ {0.5, 1}, t_hold ∈ {0, 0.5, 1} s, t_hold being the hold
after each stroke (so the period varies, 0.6–3.5 s). The 0.1 s rise exceeds the stroke servo: the
paper swept these in simulation, so the sweep passes them on unchanged.

Per geometry the table reports the maximum over controllers of
* `thrust_ratio`: paper Eq. 3;
* `normalized_thrust`: the Fig. 3 caption's ratio T̄_w / T̄_w_spine (T̄_l / T̄_l_root): mean
  thrust over that of the bare spine (a plain 10 mm strip) or bare root part (a plain feather of
  length l_root) under the same controller; undefined (NaN) where that reference thrust is not
  clearly positive.

Runs go through an `featherstar.optimizer.executor.Executor` (local processes by default, or a Dask cluster)
and are appended to a JSONL log as they complete, so a sweep killed at any point resumes with only
the missing runs. A failing run is recorded with its error instead of stopping the sweep.
"""
from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Mapping, Sequence

from ..cosim.swimmer.stroke import Stroke
from .errors import OptimizerError
from .evaluation import SWEEP_STREAM, MeasurementPlan, evaluate
from .executor import Executor, ProcessExecutor, Progress
from .log import ExperimentLog
from .resume import Entries, check_log
from .objective import Objective, preflight
from .space import stroke_overrides

W_SPINE_M = 0.010
L_ROOT_M = 0.0575
FAMILIES = ("chordwise", "spanwise")
# A reference thrust below this is indistinguishable from zero (the load cell's noise averages to
# ≈ 0.3 mN over a few periods; a flapped feather makes ≈ 25 mN): no normalized thrust then.
MIN_REFERENCE_THRUST_N = 1e-3


@dataclass(frozen=True)
class Controller:
    t_up_s: float
    t_down_s: float
    t_hold_s: float

    def stroke(self, amplitude_deg: float) -> Stroke:
        return Stroke(self.t_up_s, self.t_hold_s, self.t_down_s, self.t_hold_s, amplitude_deg)


PAPER_CONTROLLERS = tuple(
    Controller(up, down, hold) for up in (0.1, 0.5) for down in (0.5, 1.0) for hold in (0.0, 0.5, 1.0)
)


@dataclass(frozen=True)
class Geometry:
    """A feather shape; `reference` marks the bare spine / root used to normalize thrust."""

    family: str
    width_m: float
    length_m: float
    reference: bool = False

    @property
    def ratio(self) -> float:
        return self.width_m / W_SPINE_M if self.family == "chordwise" else self.length_m / L_ROOT_M

    def overrides(self) -> dict[str, str | float]:
        """Scene overrides in the feather model's own parameters: a chordwise feather is given by
        its width ratio (its width is WR × the spine's), the others by their width."""
        if self.reference:
            return {"feather.morphology": "plain", "feather.width_m": self.width_m, "feather.length_m": self.length_m}
        if self.family == "chordwise":
            return {"feather.morphology": "chordwise", "feather.width_ratio": self.ratio, "feather.length_m": self.length_m}
        return {"feather.morphology": "spanwise", "feather.width_m": self.width_m, "feather.length_m": self.length_m,
                "feather.length_ratio": self.ratio}


def paper_geometries(family: str) -> list[Geometry]:
    """The paper's sweep for one family, plus its reference geometry (last)."""
    if family == "chordwise":
        shapes = [Geometry(family, w_mm / 1000, 0.120) for w_mm in range(15, 121, 5)]
        return shapes + [Geometry(family, W_SPINE_M, 0.120, reference=True)]
    if family == "spanwise":
        shapes = [Geometry(family, 0.120, l_mm / 1000) for l_mm in range(60, 181, 10)]
        return shapes + [Geometry(family, 0.120, L_ROOT_M, reference=True)]
    raise OptimizerError(f"unknown sweep family {family!r}; known: {list(FAMILIES)}")


@dataclass(frozen=True)
class Task:
    index: int
    geometry: Geometry
    controller: Controller


def run_task(objective: Objective, task: Task, plan: MeasurementPlan, amplitude_deg: float) -> dict:
    """One sweep run, in a worker. Errors become data: one bad geometry must not sink the sweep."""
    stroke = task.controller.stroke(amplitude_deg)
    row = _task_fields(task)
    try:
        result = evaluate(
            objective, {**task.geometry.overrides(), **stroke_overrides(stroke)}, stroke.period_s, plan,
            SWEEP_STREAM, (task.index,),
        )
    except Exception as exc:  # noqa: BLE001 — recorded per row and reported after the sweep
        return {**row, "thrust_ratio": math.nan, "mean_thrust_N": math.nan, "sim_wall_s": 0.0,
                "error": f"{type(exc).__name__}: {exc}"}
    return {**row, "thrust_ratio": result.thrust_ratio, "mean_thrust_N": result.mean_thrust_N,
            "sim_wall_s": result.sim_wall_s, "error": ""}


@dataclass
class SweepResult:
    runs: list[dict]
    table: list[dict]
    wall_s: float
    workers: int  # tasks run at once: local processes or cluster threads
    resumed_runs: int = 0  # read back from the log instead of run

    @property
    def simulation_s(self) -> float:
        return sum(r["sim_wall_s"] for r in self.runs)


def sweep_tasks(families: Sequence[str], controllers: Sequence[Controller]) -> list[Task]:
    """Every geometry of `families` (plus the references) × `controllers`, indexed in that order."""
    geometries = [g for family in families for g in paper_geometries(family)]
    return [Task(i, g, c) for i, (g, c) in enumerate((g, c) for g in geometries for c in controllers)]


def run_sweep(
    objective: Objective,
    families: Sequence[str] = FAMILIES,
    *,
    controllers: Sequence[Controller] = PAPER_CONTROLLERS,
    plan: MeasurementPlan = MeasurementPlan(settle_periods=2, periods=3),
    amplitude_deg: float = 60.0,
    executor: Executor | None = None,
    log_path: str | Path | None = None,
    resume: bool = False,
    context: Mapping[str, object] | None = None,
    progress: bool = True,
) -> SweepResult:
    """Run every geometry of `families` × `controllers` (plus the references) and tabulate.

    `executor`: where runs go (default: local processes on all cores). `log_path`: every run is
    appended there (JSONL, fsync'd) as it completes, so a killed client loses nothing finished;
    `resume` skips the runs already in it. `context` (scene, overrides) goes into the log header,
    so a log is never resumed with another setup.
    """
    tasks = sweep_tasks(families, controllers)
    if not tasks:
        raise OptimizerError("the sweep plans no runs (no families or no controllers)")
    _preflight(objective, tasks, plan, amplitude_deg)
    started = time.perf_counter()
    log = None if log_path is None else ExperimentLog.open(
        log_path, _header(families, controllers, plan, amplitude_deg, context), resume=resume)
    if log is not None:
        check_log(log, [log_entries(tasks)])
    runs = {r["index"]: _row(r) for r in (log.records if log else [])}
    todo = [task for task in tasks if task.index not in runs]
    owned = executor is None
    executor = executor or ProcessExecutor()
    try:
        with Progress(len(tasks), "sweep", enabled=progress, initial=len(runs)) as bar:
            pending = {executor.submit(run_task, objective, task, plan, amplitude_deg) for task in todo}
            while pending:
                for future in executor.wait_any(pending):
                    pending.discard(future)
                    row = future.result()
                    runs[row["index"]] = row
                    if log is not None:
                        log.append({"kind": "run", **row})
                    bar.update(running=min(len(pending), executor.slots), failed=bool(row["error"]))
    finally:
        if owned:
            executor.close()
    ordered = [runs[i] for i in sorted(runs)]
    failed = [r for r in ordered if r["error"]]
    if ordered and len(failed) == len(ordered):
        raise OptimizerError(f"every sweep run failed; first error: {failed[0]['error']}")
    return SweepResult(ordered, tabulate(ordered), time.perf_counter() - started, executor.slots,
                       len(tasks) - len(todo))


def _preflight(objective: Objective, tasks: Sequence[Task], plan: MeasurementPlan, amplitude_deg: float) -> None:
    """The first run of each kind of geometry (chordwise, spanwise, a reference), planned and not
    simulated: a sweep that cannot work is refused before its first run, not after its last."""
    kinds = {}
    for task in tasks:
        kinds.setdefault((task.geometry.family, task.geometry.reference), task)
    for task in kinds.values():
        stroke = task.controller.stroke(amplitude_deg)
        preflight(objective, {**task.geometry.overrides(), **stroke_overrides(stroke)}, plan.run_length_s(stroke.period_s))


_PLANNED_FIELDS = ("family", "reference", "width_m", "length_m", "ratio", "t_up_s", "t_down_s", "t_hold_s")


def log_entries(tasks: Sequence[Task]) -> Entries:
    """What a sweep log's records must be: one run per planned task, its geometry and controller
    the task's (so a line moved to another index, or another grid's line, is refused)."""
    by_index = {task.index: task for task in tasks}

    def planned(index) -> dict | None:
        task = by_index.get(index)
        if task is None:
            return None
        return {k: v for k, v in _task_fields(task).items() if k in _PLANNED_FIELDS}

    fields = {"index": "int", "family": "str", "reference": "bool", "error": "str", "thrust_ratio": "number",
              "mean_thrust_N": "number", "sim_wall_s": "number",
              **{k: "number" for k in _PLANNED_FIELDS if k not in ("family", "reference")}}
    return Entries("run", fields, key="index", planned=planned, plan=f"runs 0..{len(tasks) - 1} of this grid")


def _task_fields(task: Task) -> dict:
    return {
        "index": task.index, "family": task.geometry.family, "reference": task.geometry.reference,
        "width_m": task.geometry.width_m, "length_m": task.geometry.length_m, "ratio": task.geometry.ratio,
        "t_up_s": task.controller.t_up_s, "t_down_s": task.controller.t_down_s, "t_hold_s": task.controller.t_hold_s,
    }


def _header(families, controllers, plan: MeasurementPlan, amplitude_deg: float, context) -> dict:
    return {
        "sweep": {"families": list(families), "amplitude_deg": amplitude_deg,
                  "controllers": [f"{c.t_up_s}/{c.t_down_s}/{c.t_hold_s}" for c in controllers]},
        "measurement": plan.describe(),
        "context": dict(context or {}),
    }


def _row(record: dict) -> dict:
    """A logged run back as a row: the log spells non-finite floats as strings ('nan')."""
    row = {k: v for k, v in record.items() if k != "kind"}
    for key in ("thrust_ratio", "mean_thrust_N", "sim_wall_s"):
        row[key] = float(row[key])
    return row


def tabulate(runs: Iterable[dict]) -> list[dict]:
    """Per geometry: the best controller by TR and the maximum normalized thrust."""
    runs = list(runs)
    references = {
        (r["family"], r["t_up_s"], r["t_down_s"], r["t_hold_s"]): r["mean_thrust_N"] for r in runs if r["reference"]
    }
    table = []
    for key in dict.fromkeys((r["family"], r["width_m"], r["length_m"]) for r in runs if not r["reference"]):
        rows = [r for r in runs if not r["reference"] and (r["family"], r["width_m"], r["length_m"]) == key]
        ok = [r for r in rows if not r["error"]]
        best = max(ok, key=lambda r: r["thrust_ratio"], default=None)
        normalized = [
            r["mean_thrust_N"] / ref
            for r in ok
            if (ref := references.get((r["family"], r["t_up_s"], r["t_down_s"], r["t_hold_s"]), math.nan))
            > MIN_REFERENCE_THRUST_N
        ]
        table.append({
            "family": key[0], "width_m": key[1], "length_m": key[2], "ratio": rows[0]["ratio"],
            "thrust_ratio": math.nan if best is None else best["thrust_ratio"],
            "best_controller": "" if best is None else f"{best['t_up_s']}/{best['t_down_s']}/{best['t_hold_s']}",
            "mean_thrust_N": max((r["mean_thrust_N"] for r in ok), default=math.nan),
            "normalized_thrust": max(normalized, default=math.nan),
            "failed_runs": len(rows) - len(ok),
        })
    return table


def normalized_thrust_note(runs: Iterable[dict], table: Sequence[dict]) -> str | None:
    """Why the table's normalized thrust is undefined for every geometry (None when some is
    defined): what the bare spine / root part made under the controllers run."""
    if any(math.isfinite(r["normalized_thrust"]) for r in table):
        return None
    references = [r for r in runs if r["reference"] and not r["error"]]
    if not references:
        return "no run of the bare spine or root part succeeded, so there is no reference thrust"
    largest = max(r["mean_thrust_N"] for r in references)
    return (f"the bare spine or root part (a plain feather) made at most {1e3 * largest:.2f} mN of mean thrust "
            f"under every controller run, below the {1e3 * MIN_REFERENCE_THRUST_N:g} mN a reference thrust needs "
            "to be told from zero")


def write_csv(rows: Sequence[dict], path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


def format_table(table: Sequence[dict]) -> str:
    lines = [f"{'family':<10} {'w mm':>6} {'l mm':>6} {'ratio':>6} {'max TR':>7} {'best up/down/hold s':>20} "
             f"{'max T̄ mN':>9} {'max T̄/T̄ref':>11}"]
    for r in table:
        lines.append(
            f"{r['family']:<10} {r['width_m'] * 1e3:6.0f} {r['length_m'] * 1e3:6.0f} {r['ratio']:6.2f} "
            f"{r['thrust_ratio']:7.3f} {r['best_controller']:>20} {r['mean_thrust_N'] * 1e3:9.2f} "
            f"{r['normalized_thrust']:11.3f}"
        )
    return "\n".join(lines)
