"""Sweeps, batched Bayesian studies and FMU builds on a real dask.distributed LocalCluster.

Every result through the cluster must equal the local-process run with the same seed: noise is
drawn per experiment from (seed, stream, index), and batches are asked deterministically.
"""
import json

import pytest
from dask_testing import FEATHER, fmu_run_on_this_worker, without_timing

from featherstar.optimizer.cli import main
from featherstar.optimizer.codesign import codesign
from featherstar.optimizer.evaluation import MeasurementPlan
from featherstar.optimizer.executor import DaskExecutor, ProcessExecutor
from featherstar.optimizer.objective import master_available
from featherstar.optimizer.space import stroke_space
from featherstar.optimizer.study import run_study
from featherstar.optimizer.sweep import Controller, run_sweep

pytestmark = pytest.mark.dask

CONTROLLERS = (Controller(0.5, 0.5, 0.5), Controller(0.5, 1.0, 1.0))
PLAN = MeasurementPlan(settle_periods=1, periods=2, seed=5)


def test_sweep_on_the_cluster_equals_the_local_run(cluster, tmp_path):
    with DaskExecutor(cluster.scheduler_address) as executor:
        assert executor.slots == 2
        remote = run_sweep(FEATHER, ["spanwise"], controllers=CONTROLLERS, plan=PLAN, executor=executor,
                           log_path=tmp_path / "runs.jsonl", progress=False)
    with ProcessExecutor(2) as executor:
        local = run_sweep(FEATHER, ["spanwise"], controllers=CONTROLLERS, plan=PLAN, executor=executor, progress=False)
    assert len(remote.runs) == 14 * 2 and remote.workers == 2
    assert without_timing(remote.runs) == without_timing(local.runs)
    assert remote.table == local.table
    logged = [json.loads(line) for line in (tmp_path / "runs.jsonl").read_text().splitlines()[1:]]
    assert sorted(r["index"] for r in logged) == list(range(28))


def test_batched_study_on_the_cluster_equals_the_local_run(cluster, tmp_path):
    space = stroke_space(1.5)
    runs = {}
    for name, executor in (("dask", DaskExecutor(cluster.scheduler_address)), ("local", ProcessExecutor(2))):
        with executor:
            runs[name] = run_study(FEATHER, space, tmp_path / name, iterations=8, plan=PLAN, batch_size=2,
                                   executor=executor)
    logs = {name: [json.loads(line) for line in (tmp_path / name / "evaluations.jsonl").read_text().splitlines()]
            for name in runs}
    evaluations = {name: [{k: v for k, v in r.items() if k not in ("sim_wall_s", "digest")} for r in log
                          if r["kind"] == "evaluation"]
                   for name, log in logs.items()}
    assert [r["index"] for r in evaluations["dask"]] == list(range(8))
    assert evaluations["dask"] == evaluations["local"]
    assert logs["dask"][0]["batch_size"] == 2
    for key in ("best_params", "thrust_ratio", "thrust_ratio_sd", "baseline_thrust_ratio", "estimated_thrust_ratio"):
        assert runs["dask"][key] == runs["local"][key], key


def test_codesign_on_the_cluster_equals_the_local_run(cluster, tmp_path):
    reports = {}
    for name, executor in (("dask", DaskExecutor(cluster.scheduler_address)), ("local", ProcessExecutor(2))):
        with executor:
            reports[name] = codesign(FEATHER, "chordwise", tmp_path / name, budget=8, plan=PLAN, batch_size=2,
                                     executor=executor)
    assert len(reports["dask"]["two_stage"]["stage1"]) == 2
    assert reports["dask"] == reports["local"]


@pytest.mark.skipif(not master_available(), reason="featherstar.cosim.run_scene (the FMU master) is not available")
def test_workers_build_each_fmu_once_without_racing(client, worker_fmu_cache):
    """Both workers start a plain-feather run at once on an empty cache: one compiles, the other
    waits for it; neither replaces the other's file (same inode), and no partial file is left."""
    assert not list(worker_fmu_cache.iterdir())
    workers = sorted(client.scheduler_info()["workers"])
    futures = [client.submit(fmu_run_on_this_worker, workers=[w], pure=False) for w in workers]
    (tr_a, pid_a, fmus_a, partial_a), (tr_b, pid_b, fmus_b, partial_b) = client.gather(futures)
    assert pid_a != pid_b
    assert tr_a == tr_b and 0.5 < tr_a < 2.0
    assert fmus_a == fmus_b and any(name.startswith("feather") for name in fmus_a)
    assert partial_a == partial_b == []


def test_cli_sweep_on_the_cluster_prints_the_dashboard(cluster, tmp_path, capsys):
    out = tmp_path / "sweep"
    assert main(["sweep", "synthetic:plain", "--family", "spanwise", "--scheduler", cluster.scheduler_address,
                 "--out", str(out), "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert f"Dask scheduler {cluster.scheduler_address}: 2 workers, 2 threads; dashboard http://127.0.0.1:" in err
    assert json.loads((out / "summary.json").read_text())["runs"] == 14 * 12
