"""`featherstar run testbed --hardware ...&clock=device` against an emulator process, with two
busy processes competing for both cores: the devices keep the time, so the run completes with
its periods valid and the flat plate's symmetric stroke measures TR 1.0 (0.998-1.000 quiet)."""
from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest

from featherstar.hil.emulator import spawn_emulator

pytestmark = [pytest.mark.hil, pytest.mark.realtime]
BUSY = [sys.executable, "-c", "while True: pass"]


def test_a_device_timed_run_under_competing_load_completes_and_measures(tmp_path, keeps_time):
    with spawn_emulator(plant="flat-plate", seed=1) as emulator:
        hogs = [subprocess.Popen(BUSY) for _ in range(2)]
        try:
            time.sleep(0.3)
            run = subprocess.run(
                [sys.executable, "-m", "featherstar", "run", "testbed", "--quiet", "--no-figure",
                 "--out", str(tmp_path),
                 "--hardware", f"servo={emulator.servo_url}&clock=device",
                 "--hardware", f"loadcell={emulator.loadcell_url}&clock=device",
                 "--set", "master.periods=4", "--set", "metrics.settle_periods=1"],
                capture_output=True, text=True, timeout=120)
        finally:
            for hog in hogs:
                hog.kill()
                hog.wait()
    assert run.returncode == 0, run.stderr
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["complete"] is True and summary["coupling"] == "device-timed"
    validity = summary["validity"]
    assert validity["valid_periods"] >= 0.9 * summary["periods_used"] and summary["periods_used"] == 3
    assert summary["thrust_ratio"] == pytest.approx(1.0, abs=0.02)
    assert summary["samples"]["lost"] == {"servo": 0, "loadcell": 0}
    assert summary["safe_position_confirmed"] == {"servo": True}
    # Every recorded sample carries the device's time: a 4 ms grid, not the PC's beat.
    rows = (tmp_path / "results.csv").read_text().splitlines()[1:]
    times = [float(r.split(",")[0]) for r in rows]
    steps = [b - a for a, b in zip(times, times[1:])]
    assert max(steps) - min(steps) < 1e-4 and abs(steps[0] - 0.004) < 1e-5


def test_clock_device_on_one_url_only_is_refused(capsys):
    from featherstar.app import main

    assert main(["run", "testbed", "--quiet",
                 "--hardware", "servo=modbus-tcp://127.0.0.1:1?unit=2&clock=device",
                 "--hardware", "loadcell=modbus-tcp://127.0.0.1:1?unit=1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "clock=device" in err[0] and "both" in err[0]
