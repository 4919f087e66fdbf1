"""Speed-up of a morphology sweep on a Dask cluster of 2 workers over 1, measured side by side.

    python bench/cluster_speedup.py [--quick] [--out docs/results]

Starts two dask.distributed LocalClusters, of one and of two single-threaded worker processes,
warms both (each worker loads the scene and its FMUs once: what a long sweep amortizes; the time
is reported), then runs the same sweep through `featherstar.optimizer.executor.DaskExecutor` on them in the
order 1, 2, 2, 1 workers and reports the ratio of summed wall times (1 worker / 2 workers) in
DIR/cluster_speedup.json. Every sweep must give the same results. The default sweep is the paper's Fig. 3 spanwise family (13 lengths plus
the root reference) under one controller, on the kinematic scene through the FMU master, as
`featherstar paper` runs it. --quick replaces the simulation with the analytic stand-in plus a
sleep (a smoke test of the machinery, not a measurement of the simulation). On a machine where
others also compute, the ratio is bounded by the cores they leave free: the JSON records the load
average and, before each cluster run, a control (`cpu_parallelism_before`: the speed-up of a
pure-Python CPU loop on 2 processes over 1 at that moment), the ceiling the sweep's ratio is
to be read against.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from distributed import Client, LocalCluster

from featherstar.optimizer.evaluation import MeasurementPlan
from featherstar.optimizer.executor import DaskExecutor
from featherstar.optimizer.objective import SceneObjective, Trace
from featherstar.optimizer.sweep import Controller, run_sweep
from featherstar.optimizer.synthetic import SyntheticFeather

RESULTS_DIR = Path(__file__).resolve().parents[1] / "docs" / "results"
FAMILY = "spanwise"
CONTROLLER = Controller(0.5, 1.0, 0.0)
PLAN = MeasurementPlan(settle_periods=1, periods=2, seed=0)
QUICK_DELAY_S = 0.2
ORDER = (1, 2, 2, 1)  # workers of each timed sweep


@dataclass(frozen=True)
class SleepingFeather:
    """The analytic stand-in, holding its worker for `delay_s` like a simulation would."""

    delay_s: float

    def __call__(self, overrides, duration_s: float) -> Trace:
        time.sleep(self.delay_s)
        return SyntheticFeather(FAMILY)(overrides, duration_s)


def _burn(iterations: int) -> float:
    started = time.perf_counter()
    total = 0
    for i in range(iterations):
        total += i
    return time.perf_counter() - started


def cpu_parallelism(iterations: int = 20_000_000) -> float:
    """The control: how much faster two pure-Python CPU loops finish in two processes than one
    after the other, right now (2.0: two free cores; 1.0: one core's worth left by other work)."""
    alone_s = _burn(iterations)
    with multiprocessing.Pool(2) as pool:
        started = time.perf_counter()
        pool.map(_burn, [iterations, iterations])
        parallel_s = time.perf_counter() - started
    return 2 * alone_s / parallel_s


def warm_up(cluster: LocalCluster, objective) -> float:
    """Seconds until every worker of `cluster` has run `warm_worker` once."""
    with Client(cluster.scheduler_address, set_as_default=False) as client:
        client.wait_for_workers(len(cluster.workers), timeout=120)
        started = time.perf_counter()
        client.gather([client.submit(warm_worker, objective, workers=[address], pure=False)
                       for address in client.scheduler_info()["workers"]])
        return time.perf_counter() - started


def measure(cluster: LocalCluster, objective, workers: int) -> dict:
    """One timed sweep on a warm cluster, with the CPU control taken just before it."""
    control = cpu_parallelism()
    with DaskExecutor(cluster.scheduler_address) as executor:
        started = time.perf_counter()
        result = run_sweep(objective, [FAMILY], controllers=[CONTROLLER], plan=PLAN, executor=executor,
                           progress=False)
        wall_s = time.perf_counter() - started
    return {
        "workers": workers, "cpu_parallelism_before": control, "wall_s": wall_s, "runs": len(result.runs),
        "failed_runs": sum(1 for r in result.runs if r["error"]), "simulation_s": result.simulation_s,
        "results": [{k: v for k, v in r.items() if k != "sim_wall_s"} for r in result.runs],
    }


def warm_worker(objective) -> None:
    """Runs on every worker before timing: the first and the reference geometry once each, so
    the scene and its FMUs are loaded (the FMU cache is shared: built at most once per host)."""
    from featherstar.optimizer.evaluation import SWEEP_STREAM, evaluate
    from featherstar.optimizer.space import stroke_overrides
    from featherstar.optimizer.sweep import paper_geometries

    stroke = CONTROLLER.stroke(60.0)
    for geometry in (paper_geometries(FAMILY)[0], paper_geometries(FAMILY)[-1]):
        evaluate(objective, {**geometry.overrides(), **stroke_overrides(stroke)}, stroke.period_s,
                 MeasurementPlan(settle_periods=0, periods=1), SWEEP_STREAM, (0,))


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="analytic stand-in + sleep instead of the FMU master")
    parser.add_argument("--out", type=Path, default=RESULTS_DIR, help="where cluster_speedup.json goes")
    args = parser.parse_args(argv)
    objective = SleepingFeather(QUICK_DELAY_S) if args.quick else SceneObjective("kinematic")
    load_before = os.getloadavg()
    started = time.perf_counter()
    clusters = {n: LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
                for n in (1, 2)}
    try:
        warm_s = {n: warm_up(cluster, objective) for n, cluster in clusters.items()}
        # ABBA: a load from other work that drifts linearly during the bench weighs on both equally.
        sweeps = [measure(clusters[n], objective, n) for n in ORDER]
    finally:
        for cluster in clusters.values():
            cluster.close()
    if any(m["results"] != sweeps[0]["results"] for m in sweeps):
        print("error: the 1- and 2-worker sweeps gave different results", file=sys.stderr)
        return 1
    wall_s = {n: sum(m["wall_s"] for m in sweeps if m["workers"] == n) for n in (1, 2)}
    report = {
        "objective": "analytic stand-in + 0.2 s sleep per run (--quick)" if args.quick
        else "FMU master, scene kinematic (the paper's sweep scene)",
        "sweep": {"family": FAMILY, "controller": f"{CONTROLLER.t_up_s}/{CONTROLLER.t_down_s}/{CONTROLLER.t_hold_s}",
                  "runs": sweeps[0]["runs"], "failed_runs": sweeps[0]["failed_runs"], "measurement": PLAN.describe()},
        "order": list(ORDER),
        "warm_up_s": {f"{n}_workers": v for n, v in warm_s.items()},
        "sweeps": [{k: v for k, v in m.items() if k != "results"} for m in sweeps],
        "wall_s": {f"{n}_workers": v for n, v in wall_s.items()},
        "speedup_1_to_2_workers": wall_s[1] / wall_s[2],
        "results_equal": True,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()},
        "load_average_before": load_before, "load_average_after": os.getloadavg(),
        "total_wall_s": time.perf_counter() - started,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "cluster_speedup.json").write_text(json.dumps(report, indent=2) + "\n")
    controls = ", ".join(f"{m['cpu_parallelism_before']:.2f}" for m in sweeps)
    print(f"sweep of {report['sweep']['runs']} runs, order {ORDER}: 1 worker {wall_s[1]:.1f} s, 2 workers "
          f"{wall_s[2]:.1f} s, speed-up {report['speedup_1_to_2_workers']:.2f}x (CPU control before each: "
          f"{controls}); wrote {args.out / 'cluster_speedup.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
