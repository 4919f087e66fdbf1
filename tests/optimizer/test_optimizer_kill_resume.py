"""A hard kill (SIGKILL) of a running optimizer, then --resume: nothing lost, nothing repeated."""
import os
import signal
import subprocess
import sys
import textwrap
import time

from optimizer_testing import FEATHER, PLAN, SHORT_ITERATIONS, SPACE, logged_evaluations

from optimizer.bayes import optimize

RUNNER = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, sys.argv[2])
    from optimizer_testing import FEATHER, PLAN, SPACE
    from optimizer.bayes import optimize

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
