"""`featherstar run testbed --hardware ...&clock=device` against an emulator process: with two
busy processes competing for both cores the devices keep the time, so the run completes with
its periods valid and the flat plate's symmetric stroke measures TR 1.0 (0.998-1.000 quiet); a
device restart or a SIGTERM midway ends it with its data kept and the servo safe."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest
from pymodbus.client import ModbusTcpClient

from featherstar.hil.codec import decode_value
from featherstar.hil.emulator import SERVO_UNIT, spawn_emulator
from featherstar.hil.registers import load_servo_map

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


def _position_deg(port: int) -> float | None:
    field = load_servo_map("servo-default").position
    with ModbusTcpClient("127.0.0.1", port=port, timeout=1.0, retries=0) as client:
        reply = client.read_holding_registers(field.address, count=2, device_id=SERVO_UNIT)
        return None if reply.isError() else decode_value(field, reply.registers)


def _start(emulator, out) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "featherstar", "run", "testbed", "--quiet", "--no-figure",
         "--out", str(out), "--hardware", f"servo={emulator.servo_url}&clock=device",
         "--hardware", f"loadcell={emulator.loadcell_url}&clock=device",
         "--set", "master.periods=4", "--set", "metrics.settle_periods=1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_until_playing(emulator, run) -> None:
    deadline = time.monotonic() + 60
    while abs(_position_deg(emulator.port) or 0.0) < 10.0:
        assert run.poll() is None, run.communicate()
        assert time.monotonic() < deadline, "the stroke never started"
        time.sleep(0.05)
    time.sleep(0.5)


@pytest.mark.parametrize("stop, status, words", [("reboot", 2, "restarted"),
                                                  ("SIGTERM", 143, "interrupted by SIGTERM")])
def test_a_device_timed_run_stopped_midway_keeps_its_data_and_the_servo_safe(tmp_path, stop,
                                                                             status, words):
    with spawn_emulator(plant="flat-plate", seed=1) as emulator:
        run = _start(emulator, tmp_path)
        try:
            _wait_until_playing(emulator, run)
            if stop == "reboot":
                emulator.reboot()       # both devices, connections kept
            else:
                run.send_signal(signal.SIGTERM)
            _, err = run.communicate(timeout=60)
        finally:
            run.kill()
        assert run.returncode == status, err
        line = next(ln for ln in err.splitlines() if ln.startswith("featherstar: error:"))
        assert words in line and "partial results" in line
        summary = json.loads((tmp_path / "summary.json").read_text())
        assert summary["complete"] is False and summary["safe_position_confirmed"] == {"servo": True}
        if stop == "reboot":
            assert {e["device"] for e in summary["hardware_events"] if e["kind"] == "restart"} \
                == {"servo", "loadcell_hw"}
        assert len((tmp_path / "results.csv").read_text().splitlines()) > 100
        time.sleep(0.5)
        assert _position_deg(emulator.port) == pytest.approx(0.0, abs=0.5)


def test_the_servo_does_not_move_before_time_zero(keeps_time):
    # A stroke that starts away from rest (a ±75° stroke starts at -75°; the servo rests at 0):
    # the player holds sample 0 from arming, 0.3 s before time zero, so sample 0 must be where
    # the servo is. With the first step's command there, the servo had moved one rate-limited
    # step (0.031 rad) before time zero, and the feather was already moving at t = 0.
    from featherstar.optimizer.bench.run import run_on_bench

    stroke = {"controller.amplitude_deg": 150.0, "controller.log10_up_down": 0.6, "controller.period_s": 1.0,
              "master.step_s": 0.005, "master.t_end_s": 0.5, "metrics.settle_periods": 0,
              "master.check_steps": False}   # the servo's timing is tested here, not the metrics
    with spawn_emulator(plant="flat-plate", noise_N=0.0, seed=1) as emulator:
        run = run_on_bench("testbed", {"servo": f"{emulator.servo_url}&clock=device",
                                       "loadcell": f"{emulator.loadcell_url}&clock=device"}, stroke)
    at_zero = [a for t, a in zip(run.time_s, run.angle_rad) if t <= 1e-9]
    assert at_zero and max(abs(a) for a in at_zero) < 2e-4, at_zero   # the servo's 0.01° resolution
    # and it starts moving at time zero, not a period later (the flat plate's servo lags its
    # command by its own dynamics: a few ms)
    moving = next(t for t, a in zip(run.time_s, run.angle_rad) if abs(a) > 1e-3)
    assert 0.0 < moving <= 0.02, moving
