"""Running a scene: `run_scene(scene, overrides) -> RunResult`.

The steps leave separate artefacts: the Scene (frozen data) → with overrides (a new Scene) →
the Plan (resolved blocks, pruning, deduplication, loops; cosim.graph) → runtime units and a
RunContext (cosim.master) → the RunResult (recorded signals, summary).
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .errors import RunInterrupted, SceneError, StepError
from .fmi_types import typed_signal
from .graph import Plan, plan as make_plan
from .master import RunContext, make_context
from .strong import run_strong
from .weak import run_weak
from .metrics import scene_metrics
from .preflight import cached_fmu, check_metric_window, check_run_size
from .validity import apply_validity
from .scene import Scene, load_scene
from .units import ModelUnit, PyUnit, Unit


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


def _build_units(plan: Plan) -> dict[str, Unit]:
    master = plan.scene.master
    units: dict[str, Unit] = {}
    for name in plan.instantiate:
        rb = plan.blocks[name]
        if rb.spec.kind == "recorder":
            continue
        if rb.obj is not None:
            units[name] = PyUnit(rb.obj)
        elif rb.model is not None and master.backend == "casadi":
            units[name] = ModelUnit(name, rb.model, rb.parameters)
        elif rb.model is not None:
            from .fmu_block import FmuUnit, model_fmu_info

            try:
                from fmu_src.export import build_fmu
            except ImportError as exc:
                raise SceneError(f"block '{name}': FMU export is not available ({exc}); "
                                 "set master.backend = casadi to run models in-process") from None
            path = cached_fmu(rb.model, build_fmu, f"block '{name}'")
            info = model_fmu_info(rb.model, Path(path), name)
            units[name] = FmuUnit(name, info, rb.parameters, _fmu_mode(master.coupling, info, name))
        elif rb.fmu_info is not None:
            from .fmu_block import FmuUnit

            units[name] = FmuUnit(name, rb.fmu_info, rb.parameters, _fmu_mode(master.coupling, rb.fmu_info, name))
        else:  # pragma: no cover
            raise SceneError(f"block '{name}' ({rb.spec.kind}) cannot be instantiated")
    return units


def _fmu_mode(coupling: str, info: Any, name: str) -> str:
    if coupling == "strong":
        if not info.has_me:
            raise SceneError(f"block '{name}': the FMU has no Model Exchange interface, needed by "
                             "master.coupling = strong; use jacobi or gauss-seidel")
        return "me"
    return "cs" if info.has_cs else "me"


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
    A real-time run whose metric window has too few valid periods (cosim.validity) returns
    with `complete = False`.
    """
    wall0 = time.perf_counter()
    base = load_scene(scene)
    sc = base.with_overrides(overrides)
    plan = make_plan(sc, outputs)
    check_run_size(plan)
    if strict_window or sc.master.realtime:
        check_metric_window(plan)
    t0, t_end = 0.0, plan.t_end_s
    t_build = time.perf_counter()
    units = _build_units(plan)
    ctx = make_context(plan, units)
    ctx.stats["build_s"] = time.perf_counter() - t_build
    bar = _Progress(t_end, sc.name) if progress else None
    ctx.progress = bar
    error: StepError | None = None
    started: list[Unit] = []
    try:
        for u in units.values():
            ctx.t = t0
            started.append(u)
            u.start(t0, t_end, sc.master.rtol)
        if sc.master.coupling == "strong":
            run_strong(ctx, t0, t_end)
        else:
            run_weak(ctx, t0, t_end)
    except StepError as exc:
        error = exc
    except KeyboardInterrupt as exc:   # Ctrl-C, or RunInterrupted raised by a signal handler
        cause = exc.signal_name if isinstance(exc, RunInterrupted) else "SIGINT"
        error = StepError("master", ctx.t, f"interrupted by {cause}",
                          cause="the run was stopped from outside")
        error.interrupted = cause
    except Exception as exc:   # a bug must still close the blocks and keep the data
        error = StepError("master", ctx.t, f"internal error: {type(exc).__name__}: {exc}",
                          cause="a defect in featherstar; please report it with the scene")
    finally:
        for u in started:
            u.close()
        if bar is not None:
            bar.close()
    result = _result(plan, ctx, time.perf_counter() - wall0, overrides, error, units)
    if error is not None:
        error.partial = result
        raise error
    return result


def _loop_stats(ctx: RunContext) -> list[dict[str, Any]]:
    merged: dict[str, dict[str, Any]] = {}
    for solver in ctx.loop_solvers:  # one solver per schedule (rhs, recording, start): merge
        entry = merged.setdefault(solver.description, {"loop": solver.description, "solves": 0, "iterations": 0})
        entry["solves"] += solver.solves
        entry["iterations"] += solver.iterations
    return list(merged.values())


def _hardware_events(units: Mapping[str, Unit]) -> list[dict[str, Any]]:
    """Recoveries and reconnects the hardware blocks noted (their `events` list), by time."""
    events = [dict(e) for u in units.values()
              for e in getattr(getattr(u, "block", None), "events", None) or ()]
    return sorted(events, key=lambda e: float(e.get("t_s", 0.0)))


def _realtime_summary(plan: Plan, ctx: RunContext, units: Mapping[str, Unit], t: np.ndarray,
                      signals: Mapping[str, np.ndarray], summary: dict[str, Any],
                      finished: bool) -> bool:
    """Deadline misses, gaps and reconnects into the summary; the validity verdict when the
    run finished. Returns whether the run's result can be trusted."""
    sc = plan.scene
    events = _hardware_events(units)
    late = ctx.late_steps
    summary["deadline_misses"] = len(late)
    summary["worst_lateness_s"] = max((s for _, s in late), default=0.0)
    summary["gaps"] = sum(e.get("kind") == "gap" for e in events)
    summary["reconnects"] = sum(e.get("kind") == "reconnect" for e in events)
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
    return apply_validity(summary, t, thrust, plan.period_s, sc.master.step_s, late, events)


def _result(plan: Plan, ctx: RunContext, wall: float, overrides: Mapping[str, Any] | None,
            error: StepError | None, units: Mapping[str, Unit] | None = None) -> RunResult:
    sc = plan.scene
    # An interrupt can land between a time stamp and its row: keep whole samples only.
    n = min(len(ctx.rows), len(ctx.times))
    del ctx.rows[n:], ctx.times[n:]
    t = np.asarray(ctx.times, dtype=float)
    data = np.asarray(ctx.rows, dtype=float).reshape(n, len(plan.requested))
    signals = {str(ref): typed_signal(plan.blocks[ref.block].outputs[ref.port].type, data[:, j].copy())
               for j, ref in enumerate(plan.requested)}
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
    if error is not None:
        summary.update(error=str(error), failed_block=error.block, failed_at_s=error.t_s)
    complete = error is None
    if sc.master.realtime:
        trusted = _realtime_summary(plan, ctx, units or {}, t, signals, summary,
                                    finished=error is None and n > 1)
        if error is None and not trusted:
            complete = False
            summary["incomplete_reason"] = summary["validity"]["reason"]
    info = {
        "instantiated": list(plan.instantiate),
        "aliases": {k: v for k, v in plan.alias_of.items() if k != v},
        "pruned": list(plan.pruned),
        "notes": list(plan.notes),
        "ignored": [f"{n}: {note}" for n in plan.instantiate for note in plan.blocks[n].notes],
        "stats": dict(ctx.stats),
        "loops": _loop_stats(ctx),
        "overrides": {k: str(v) for k, v in (overrides or {}).items()},
        "scene_fingerprint": sc.fingerprint(),
    }
    summary["stats"] = info["stats"]
    return RunResult(sc, t, signals, port_units, summary, info, complete=complete)
