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


CLI_SWEEP = textwrap.dedent("""
    import sys, time
    from featherstar.app import main
    from featherstar.optimizer.synthetic import SyntheticFeather

    fast = SyntheticFeather.__call__
    def slow(self, overrides, duration_s):   # a slower experiment, so the kill lands mid-sweep
        time.sleep(0.2)
        return fast(self, overrides, duration_s)
    SyntheticFeather.__call__ = slow
    sys.exit(main(["sweep", "synthetic:plain", "--family", "spanwise", "--workers", "2", "--no-progress",
                   "--out", sys.argv[1]]))
""")


def _children(pid: int) -> list[int]:
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as handle:
                    if int(handle.read().rsplit(")", 1)[1].split()[1]) == pid:
                        found.append(int(entry))
            except (FileNotFoundError, ProcessLookupError, IndexError, ValueError):
                continue
    return found


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_kill_9_of_featherstar_sweep_takes_its_workers_along(tmp_path):
    """The command itself, killed mid-sweep: its pool's workers are gone within a second; the
    finished runs are in the log and --resume runs only the rest."""
    from featherstar.app import main

    script = tmp_path / "sweep.py"
    script.write_text(CLI_SWEEP)
    out = tmp_path / "sweep"
    parent = subprocess.Popen([sys.executable, str(script), str(out)], stderr=subprocess.DEVNULL)
    workers = []
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and parent.poll() is None:
            log = out / "runs.jsonl"
            if log.exists() and len(log.read_bytes().splitlines()) >= 4:
                break
            time.sleep(0.05)
        workers = _children(parent.pid)
        assert parent.poll() is None and len(workers) == 2, "the sweep finished or died before it could be killed"
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(timeout=10)
        killed = time.monotonic()
        while any(_alive(pid) for pid in workers) and time.monotonic() - killed < 5:
            time.sleep(0.05)
        assert not [pid for pid in workers if _alive(pid)], "workers outlived the killed sweep"
        assert time.monotonic() - killed < 1.0
    finally:
        parent.kill()
        for pid in workers:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
    assert main(["sweep", "synthetic:plain", "--family", "spanwise", "--workers", "1", "--no-progress", "--resume",
                 "--out", str(out)]) == 0
    assert json.loads((out / "summary.json").read_text())["resumed_runs"] >= 3
