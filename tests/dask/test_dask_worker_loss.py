"""A worker process killed mid-sweep: its tasks run again on the other worker, and every result
arrives exactly once (in the result and in the streamed log), equal to the local run."""
import json
import os
import signal
import threading
import time

import pytest
from dask_testing import SlowFeather, without_timing

from featherstar.optimizer.evaluation import MeasurementPlan
from featherstar.optimizer.executor import DaskExecutor, InlineExecutor
from featherstar.optimizer.sweep import Controller, run_sweep

pytestmark = pytest.mark.dask

PLAN = MeasurementPlan(settle_periods=1, periods=2, seed=11)
CONTROLLERS = (Controller(0.5, 1.0, 0.5),)
DELAY_S = 0.4  # 14 runs on 2 workers: ~3 s, long enough to kill a worker in the middle


def _logged_indices(path):
    if not path.exists():
        return []
    return [json.loads(line)["index"] for line in path.read_text().splitlines()[1:] if line.endswith("}")]


def test_a_worker_killed_mid_sweep_loses_nothing_and_duplicates_nothing(cluster, client, tmp_path):
    log = tmp_path / "runs.jsonl"
    pids = client.run(os.getpid)  # worker address -> pid
    victim_pid = sorted(pids.values())[0]
    done_at_kill = []

    def kill_when_a_few_are_done():
        deadline = time.monotonic() + 60
        while len(_logged_indices(log)) < 3 and time.monotonic() < deadline:
            time.sleep(0.02)
        os.kill(victim_pid, signal.SIGKILL)
        done_at_kill.append(len(_logged_indices(log)))

    killer = threading.Thread(target=kill_when_a_few_are_done, daemon=True)
    with DaskExecutor(cluster.scheduler_address) as executor:
        killer.start()
        remote = run_sweep(SlowFeather(DELAY_S), ["spanwise"], controllers=CONTROLLERS, plan=PLAN, executor=executor,
                           log_path=log, progress=False)
    killer.join()
    assert done_at_kill and 3 <= done_at_kill[0] < 14  # killed mid-sweep, with runs still to do
    assert sorted(_logged_indices(log)) == list(range(14))  # each run exactly once on disk
    assert [r["index"] for r in remote.runs] == list(range(14)) and not any(r["error"] for r in remote.runs)
    local = run_sweep(SlowFeather(0.0), ["spanwise"], controllers=CONTROLLERS, plan=PLAN, executor=InlineExecutor(),
                      progress=False)
    assert without_timing(remote.runs) == without_timing(local.runs)
    # The nanny replaced the killed process; the cluster is whole again for whatever runs next.
    client.wait_for_workers(2, timeout=60)
    assert victim_pid not in client.run(os.getpid).values()
