"""A hard kill (SIGKILL) of a running optimizer, then --resume: nothing lost, nothing repeated."""
import json
import os
import signal
import subprocess
import sys
import textwrap
import time

from optimizer_testing import FEATHER, PLAN, SHORT_ITERATIONS, SPACE, logged_evaluations

from featherstar.optimizer.bayes import optimize
from featherstar.optimizer.executor import InlineExecutor
from featherstar.optimizer.sweep import Controller, run_sweep

RUNNER = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, sys.argv[2])
    from optimizer_testing import FEATHER, PLAN, SPACE
    from featherstar.optimizer.bayes import optimize

    def slow_feather(overrides, duration_s):
        time.sleep(0.1)  # a slower experiment, so the kill lands mid-run
        return FEATHER(overrides, duration_s)

    optimize(slow_feather, SPACE, sys.argv[1], iterations=int(sys.argv[3]), plan=PLAN)
""")


def test_sigkill_mid_run_then_resume(short_run, tmp_path):
    log = tmp_path / "evaluations.jsonl"
    script = tmp_path / "runner.py"
    script.write_text(RUNNER)
    process = subprocess.Popen(
        [sys.executable, str(script), str(log), os.path.dirname(__file__), str(SHORT_ITERATIONS)]
    )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and process.poll() is None:
            if log.exists() and len(logged_evaluations(log)) >= 5:
                break
            time.sleep(0.02)
        assert process.poll() is None, "the optimizer finished or died before it could be killed"
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait(timeout=30)
    assert process.returncode == -signal.SIGKILL
    before = logged_evaluations(log)
    assert 5 <= len(before) < SHORT_ITERATIONS

    optimize(FEATHER, SPACE, log, iterations=SHORT_ITERATIONS, plan=PLAN, resume=True)
    after = logged_evaluations(log)
    assert [r["index"] for r in after] == list(range(SHORT_ITERATIONS))  # none lost, none repeated
    assert after[: len(before)] == before  # the logged ones were kept, not re-run
    assert after == logged_evaluations(short_run)  # and the run is the one that was never killed


SWEEP_RUNNER = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, sys.argv[2])
    from optimizer_testing import FEATHER
    from featherstar.optimizer.executor import ProcessExecutor
    from featherstar.optimizer.sweep import Controller, run_sweep

    def slow_feather(overrides, duration_s):
        time.sleep(0.05)  # a slower experiment, so the kill lands mid-sweep
        return FEATHER(overrides, duration_s)

    with ProcessExecutor(2) as executor:
        run_sweep(slow_feather, ["spanwise"], controllers=[Controller(0.5, 1.0, 0.5), Controller(0.5, 0.5, 0.0)],
                  executor=executor, log_path=sys.argv[1], progress=False)
""")


def test_sigkill_of_a_sweep_client_then_resume(tmp_path):
    """The client is killed while its workers are busy: every run it had logged survives, and the
    resumed sweep runs only the rest (no index twice), ending equal to a sweep never killed."""
    log = tmp_path / "runs.jsonl"
    script = tmp_path / "sweep_runner.py"
    script.write_text(SWEEP_RUNNER)
    process = subprocess.Popen([sys.executable, str(script), str(log), os.path.dirname(__file__)],
                               start_new_session=True)  # its pool workers die with the group below

    def logged():
        return [json.loads(line) for line in log.read_text().splitlines()[1:] if line.endswith("}")] if log.exists() else []

    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and process.poll() is None and len(logged()) < 5:
            time.sleep(0.02)
        assert process.poll() is None, "the sweep finished or died before it could be killed"
        os.killpg(process.pid, signal.SIGKILL)
    finally:
        process.wait(timeout=30)
    before = {r["index"] for r in logged()}
    assert 5 <= len(before) < 28

    controllers = [Controller(0.5, 1.0, 0.5), Controller(0.5, 0.5, 0.0)]
    resumed = run_sweep(FEATHER, ["spanwise"], controllers=controllers, executor=InlineExecutor(), log_path=log,
                        resume=True, progress=False)
    assert resumed.resumed_runs == len(before)
    assert sorted(r["index"] for r in logged()) == list(range(28))
    fresh = run_sweep(FEATHER, ["spanwise"], controllers=controllers, executor=InlineExecutor(), progress=False)
    assert [{k: v for k, v in r.items() if k != "sim_wall_s"} for r in resumed.runs] == \
           [{k: v for k, v in r.items() if k != "sim_wall_s"} for r in fresh.runs]
