"""Wall time of the optimizer's two workloads and where it goes: simulation or optimizer.

    python bench/optimizer_timing.py [--quick] [--scene testbed] [--set master.method=adams ...]

1. a 30-iteration stroke optimization (chordwise WR 7.5, 1.5 s), without and with the validation;
2. the paper's full morphology sweep (35 geometries + 2 references × 12 controllers = 444 runs) on
   all local cores.

Goals (issue): 30 iterations < 60 s, the full sweep < 2 min on the 2-core machine. Uses the FMU
master when `featherstar.cosim.run_scene` exists, else the analytic stand-in (then the numbers measure the
optimizer's own overhead only, and the JSON says so; --synthetic forces that, into
optimizer_timing_synthetic.json). --quick: 10 iterations, one sweep family with two controllers (a
smoke test, not the goal numbers). Writes bench/results/optimizer_timing.json.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

from featherstar.optimizer.bayes import optimize
from featherstar.optimizer.evaluation import MeasurementPlan
from featherstar.optimizer.objective import SceneObjective, WithOverrides, master_available
from featherstar.optimizer.space import stroke_space
from featherstar.optimizer.study import summarize
from featherstar.optimizer.sweep import FAMILIES, PAPER_CONTROLLERS, run_sweep
from featherstar.optimizer.synthetic import SyntheticFeather

RESULTS_DIR = Path(__file__).parent / "results"
CHORDWISE_75 = {"feather.morphology": "chordwise", "feather.width_ratio": 7.5}


def bench_optimization(objective, iterations: int) -> dict:
    space = stroke_space(1.5)
    plan = MeasurementPlan(seed=0)
    with tempfile.TemporaryDirectory() as tmp:
        started = time.perf_counter()
        run = optimize(objective, space, Path(tmp) / "evaluations.jsonl", iterations=iterations, plan=plan)
        optimization_s = time.perf_counter() - started
        summary = summarize(objective, space, run, maximize=True, plan=plan)
    return {
        "iterations": iterations,
        "wall_s": optimization_s,
        "simulation_s": run.timing_s["simulation_s"],
        "optimizer_s": run.timing_s["optimizer_s"],
        "simulation_share": run.timing_s["simulation_s"] / optimization_s,
        "validation_wall_s": summary["timing_s"]["validation_s"],
        "best_thrust_ratio": summary["thrust_ratio"],
        "baseline_thrust_ratio": summary["baseline_thrust_ratio"],
        "goal_s": 60.0,
    }


def bench_sweep(objective, quick: bool) -> dict:
    families = FAMILIES[:1] if quick else FAMILIES
    controllers = PAPER_CONTROLLERS[:2] if quick else PAPER_CONTROLLERS
    result = run_sweep(objective, families, controllers=controllers, progress=False)
    capacity_s = result.wall_s * (result.workers or 1)
    return {
        "runs": len(result.runs),
        "failed_runs": sum(1 for r in result.runs if r["error"]),
        "workers": result.workers,
        "wall_s": result.wall_s,
        "simulation_s": result.simulation_s,
        "simulation_share_of_worker_time": result.simulation_s / capacity_s,
        "goal_s": 120.0,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", type=Path, default=RESULTS_DIR, help=f"where the JSON goes (default {RESULTS_DIR})")
    parser.add_argument("--scene", default="testbed", help="cosim scene of the single-feather test bed")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="scene override for every run (e.g. master.method=adams)")
    parser.add_argument("--synthetic", action="store_true", help="time the optimizer's overhead on the stand-in")
    args = parser.parse_args()
    overrides = dict(item.split("=", 1) for item in args.overrides)
    if master_available() and not args.synthetic:
        optimization_objective = SceneObjective(args.scene, {**overrides, **CHORDWISE_75})
        sweep_objective = SceneObjective(args.scene, overrides)
        kind = f"FMU master, scene {args.scene}, overrides {overrides}"
    else:
        optimization_objective = WithOverrides(SyntheticFeather(), CHORDWISE_75)
        sweep_objective = SyntheticFeather()
        kind = "analytic stand-in (featherstar.optimizer.synthetic): optimizer overhead only"
    report = {
        "objective": kind,
        "quick": args.quick,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()},
        "load_average_at_start": os.getloadavg(),
        "optimization": bench_optimization(optimization_objective, 10 if args.quick else 30),
        "sweep": bench_sweep(sweep_objective, args.quick),
    }
    # the stand-in's overhead numbers go beside, never over, the master's
    results = args.out / ("optimizer_timing_synthetic.json" if args.synthetic else "optimizer_timing.json")
    results.parent.mkdir(parents=True, exist_ok=True)
    results.write_text(json.dumps(report, indent=2) + "\n")
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
