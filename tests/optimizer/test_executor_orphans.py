"""kill -9 of a process with a local pool: its workers die with it, within a few seconds."""
import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from featherstar.optimizer import lifeline

RUNNER = textwrap.dedent("""
    import json, multiprocessing, sys, threading, time
    from featherstar.optimizer import lifeline
    from featherstar.optimizer.executor import ProcessExecutor

    if sys.argv[1] == "watchdog-only":   # as on a platform without prctl
        lifeline.sys.platform = "other"
    with ProcessExecutor(2) as executor:
        futures = [executor.submit(time.sleep, 600) for _ in range(2)]   # both workers busy, forever
        time.sleep(0.5)
        print(json.dumps([p.pid for p in multiprocessing.active_children()]), flush=True)
        time.sleep(600)
""")


def _alive(pid: int) -> bool:
    """Running or sleeping; a zombie (dead, not yet reaped by its new parent) counts as gone."""
    try:
        with open(f"/proc/{pid}/stat") as handle:
            return handle.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("mode", ["prctl", "watchdog-only"])
def test_workers_die_with_a_killed_parent(tmp_path, mode):
    script = tmp_path / "pool.py"
    script.write_text(RUNNER)
    parent = subprocess.Popen([sys.executable, str(script), mode], stdout=subprocess.PIPE, text=True)
    try:
        workers = json.loads(parent.stdout.readline())
        assert len(workers) == 2 and all(_alive(pid) for pid in workers)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(timeout=10)
        killed = time.monotonic()
        while any(_alive(pid) for pid in workers) and time.monotonic() - killed < 5:
            time.sleep(0.05)
        gone_after_s = time.monotonic() - killed
        survivors = [pid for pid in workers if _alive(pid)]
    finally:
        parent.kill()
        for pid in workers if "workers" in locals() else []:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
    assert not survivors, f"workers {survivors} outlived their parent by {gone_after_s:.1f} s"
    limit_s = 0.5 if mode == "prctl" else 2 * lifeline.WATCH_INTERVAL_S + 0.5
    assert gone_after_s < limit_s
