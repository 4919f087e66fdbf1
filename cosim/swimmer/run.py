"""Running a scene in one call: `run_scene(scene, overrides) -> RunResult`.

The steps leave separate artefacts: the Scene (frozen data) → with overrides (a new Scene) →
the Plan (resolved blocks, pruning, deduplication, loops; featherstar.cosim.scene.graph) → a Simulator
(featherstar.cosim.coupling.simulator) driven from start to end → the RunResult (recorded signals, summary).
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..coupling.context import Context
from ..coupling.simulator import Simulator
from ..errors import RunInterrupted, SceneError, StepError
from ..framework.units import Unit
from ..scene.data import Scene
from ..scene.graph import plan as make_plan
from ..scene.plan import Plan
from ..scene.preflight import check_metric_window, check_run_size
from ..scenes import load_scene, name_file
from .metrics import failed_preconditions, judge_valid_periods, sample_times, scene_metrics
from .validity import apply_validity


@dataclass
class RunResult:
    """Recorded signals (by "block.port" name, numpy arrays on `time`) and the summary."""

    scene: Scene
    time: np.ndarray
    signals: dict[str, np.ndarray]
    units: dict[str, str]
    summary: dict[str, Any]
    info: dict[str, Any] = field(default_factory=dict)
    complete: bool = True

    def __getitem__(self, name: str) -> np.ndarray:
        return self.signals[name]


class _Progress:
    def __init__(self, t_end: float, label: str) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=round(t_end, 6), unit="s sim", file=sys.stderr, desc=label, leave=False,
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.2f}/{total:.2f} s sim [{elapsed}<{remaining}]")

    def __call__(self, t: float) -> None:
        self.bar.n = round(t, 6)
        self.bar.refresh()

    def close(self) -> None:
        self.bar.close()


def run_scene(
    scene: str | Path | Scene,
    overrides: Mapping[str, str | float] | None = None,
    *,
    outputs: Sequence[str] | None = None,
    progress: bool = False,
    strict_window: bool = False,
) -> RunResult:
    """Run a scene (name, path or Scene) with "block.param" overrides.

    outputs: signals to record ("block.port"); default: the recorders' signals. The metrics'
    signals are always recorded. Only blocks feeding these signals are instantiated.
    strict_window: refuse a settling time that leaves no whole period to measure (the command
    line does; short API runs may measure what is there).
    Raises SceneError before anything runs, StepError on a failure during the run (with
    `.partial`, a RunResult of what was computed so far). An interrupt (Ctrl-C, or
    RunInterrupted from a signal handler) and an unexpected exception inside the master become a
    StepError of block 'master' too, after every started block was closed (a hardware servo
    commands its safe position on close): no path leaves the bench running or loses the data.
    A run whose metrics' preconditions do not all hold (featherstar.cosim.swimmer.metrics: whole
    periods, enough samples per period, finite values; for a real-time run also enough valid
    periods, featherstar.cosim.swimmer.validity) returns with `complete = False`, the failed ones
    named in `summary["incomplete_reason"]`.
    """
    wall0 = time.perf_counter()
    plan = prepare(scene, overrides, outputs=outputs, strict_window=strict_window)
    sc = plan.scene
    bar = _Progress(plan.t_end_s, sc.name) if progress else None
    sim = Simulator(plan, progress=bar)
    error: StepError | None = None
    try:
        sim.initialize(0.0)
        sim.advance_to(plan.t_end_s)
    except StepError as exc:
        error = exc
    except KeyboardInterrupt as exc:   # Ctrl-C, or RunInterrupted raised by a signal handler
        cause = exc.signal_name if isinstance(exc, RunInterrupted) else "SIGINT"
        error = StepError("master", sim.t, f"interrupted by {cause}",
                          cause="the run was stopped from outside")
        error.interrupted = cause
    except Exception as exc:   # a bug must still close the blocks and keep the data
        error = StepError("master", sim.t, f"internal error: {type(exc).__name__}: {exc}",
                          cause="a defect in featherstar; please report it with the scene")
    finally:
        sim.close()
        if bar is not None:
            bar.close()
    result = _result(plan, sim, time.perf_counter() - wall0, overrides, error)
    if error is not None:
        error.partial = result
        raise error
    return result


def prepare(scene: str | Path | Scene, overrides: Mapping[str, str | float] | None = None, *,
            outputs: Sequence[str] | None = None, strict_window: bool = False) -> Plan:
    """Every check before work, in order: the scene (file, schema), the overrides, the plan
    (wiring, ranges, step guards), the run's size and (strict_window or real time) its metric
    window. A SceneError from any of them names the scene's file when it has one."""
    base = load_scene(scene)
    try:
        sc = base.with_overrides(overrides)
        plan = make_plan(sc, outputs)
        check_run_size(plan)
        if strict_window or sc.master.realtime:
            check_metric_window(plan)
    except SceneError as exc:
        raise name_file(exc, base.source) from None
    return plan


def _loop_stats(context: Context) -> list[dict[str, Any]]:
    merged: dict[str, dict[str, Any]] = {}
    for solver in context.loop_solvers:  # one solver per schedule (rhs, recording, start): merge
        entry = merged.setdefault(solver.description, {"loop": solver.description, "solves": 0, "iterations": 0})
        entry["solves"] += solver.solves
        entry["iterations"] += solver.iterations
    return list(merged.values())


def _hardware_events(units: Mapping[str, Unit]) -> list[dict[str, Any]]:
    """Recoveries, reconnects and lag reports the hardware blocks noted (their `events` list), by time."""
    events = [dict(e) for u in units.values()
              for e in getattr(getattr(u, "block", None), "events", None) or ()]
    return sorted(events, key=lambda e: float(e.get("t_s", 0.0)))


def _realtime_summary(plan: Plan, context: Context, units: Mapping[str, Unit], t: np.ndarray,
                      signals: Mapping[str, np.ndarray], summary: dict[str, Any],
                      finished: bool) -> bool:
    """Deadline misses, gaps, reconnects and lag reports into the summary; the validity verdict when the
    run finished. Returns whether the run's result can be trusted."""
    sc = plan.scene
    events = _hardware_events(units)
    late = context.late_steps
    summary["deadline_misses"] = len(late)
    summary["worst_lateness_s"] = max((s for _, s in late), default=0.0)
    summary["gaps"] = sum(e.get("kind") == "gap" for e in events)
    summary["reconnects"] = sum(e.get("kind") == "reconnect" for e in events)
    summary["lags"] = sum(e.get("kind") == "lag" for e in events)
    summary["hardware_events"] = events[:100]   # bounded: a flapping link must not bloat it
    warnings = [f"{name}: {w}" for name, u in units.items()
                for w in getattr(getattr(u, "block", None), "warnings", None) or ()]
    if warnings:
        summary["warnings"] = warnings
    safe = {name: u.block.safe_confirmed for name, u in units.items()
            if getattr(getattr(u, "block", None), "safe_confirmed", None) is not None}
    if safe:
        summary["safe_position_confirmed"] = safe
    if not finished:
        return False
    thrust = signals.get(sc.metrics.thrust) if sc.metrics.thrust else None
    # the thrust's own sample times (a streaming load cell's reads), as its metrics used
    t_thrust = sample_times(t, signals, sc.metrics.thrust)[0] if thrust is not None else t
    return apply_validity(summary, t_thrust, thrust, plan.period_s, sc.master.step_s, late, events)


def _result(plan: Plan, sim: Simulator, wall: float, overrides: Mapping[str, Any] | None,
            error: StepError | None) -> RunResult:
    sc = plan.scene
    context, units = sim.context, sim.units
    # An interrupt can land between a time stamp and its row: keep whole samples only.
    t, signals = sim.recorded()
    n = len(t)
    port_units = {str(ref): plan.blocks[ref.block].outputs[ref.port].unit
                  for ref in plan.requested}
    summary: dict[str, Any] = {
        "scene": sc.name,
        "coupling": sc.master.coupling,
        "wall_time_s": wall,
        "t_end_s": plan.t_end_s,
        "period_s": plan.period_s,
    }
    if sc.master.coupling == "strong":
        summary.update(method=sc.master.method, rtol=sc.master.rtol, atol=sc.master.atol)
    else:
        summary.update(step_s=sc.master.step_s, adaptive=sc.master.adaptive)
    if error is None and n > 1:
        summary.update(scene_metrics(sc.metrics, plan.period_s, t, signals))
    elif error is None and sc.metrics.signals():
        summary["preconditions"] = {"recorded_samples": f"the run recorded {n} sample(s)"}
    if error is not None:
        summary.update(error=str(error), failed_block=error.block, failed_at_s=error.t_s)
    if sim.ended is not None:   # a model that said it is done (FMI terminateSimulation): not an error
        by, t_stop = sim.ended
        summary.update(terminated_by=by, terminated_at_s=t_stop)
        eps = 1e-12 * max(1.0, abs(t_stop))   # the macro grid's own rounding is not "inside"
        inside = {n: u.terminated_at_s for n, u in units.items()
                  if u.terminated_at_s is not None and u.terminated_at_s < t_stop - eps}
        if inside:
            summary["terminated_note"] = "; ".join(
                f"{n} stopped at t={t_s!r} s inside the last macro step" for n, t_s in inside.items()
            ) + f": the run ended at the communication point t={t_stop!r} s (a master.step_s that lands on it ends there)"
    if sc.master.realtime:
        finished = error is None and n > 1
        trusted = _realtime_summary(plan, context, units, t, signals, summary, finished=finished)
        if finished and sc.metrics.thrust:
            judge_valid_periods(summary, sample_times(t, signals, sc.metrics.thrust)[0],
                                signals[sc.metrics.thrust], plan.period_s, trusted)
    failed = failed_preconditions(summary)
    complete = error is None and not failed
    if error is None and failed:
        summary["incomplete_reason"] = "; ".join(f"{name}: {why}" for name, why in failed.items())
    info = {
        "instantiated": list(plan.instantiate),
        "aliases": {k: v for k, v in plan.alias_of.items() if k != v},
        "pruned": list(plan.pruned),
        "notes": list(plan.notes),
        "ignored": [f"{n}: {note}" for n in plan.instantiate for note in plan.blocks[n].notes],
        "stats": dict(context.stats),
        "loops": _loop_stats(context),
        "overrides": {k: str(v) for k, v in (overrides or {}).items()},
        "scene_fingerprint": sc.fingerprint(),
    }
    summary["stats"] = info["stats"]
    return RunResult(sc, t, signals, port_units, summary, info, complete=complete)
