"""Fault injection: `featherstar run testbed` with both devices swapped for an emulator process,
then the emulator killed and restarted, frozen for 1 s, or the run itself sent SIGTERM / SIGINT.

Each case asserts the exit status, the one-line message, the partial data on disk, the
summary's validity flags and the servo's final setpoint read back from the device (the safe
position, 0 rad). The analytic flat-plate plant keeps the emulator quick to start; the run is
4 stroke periods (6 s) of the testbed scene.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pymodbus.client import ModbusTcpClient

from featherstar.hil.codec import decode_value
from featherstar.hil.emulator import SERVO_UNIT, spawn_emulator
from featherstar.hil.registers import load_servo_map

# Streamed real-time runs with faults injected while they run: margins (0.5 s requests, waits
# for the stroke to move, not sleeps), no keeps_time gate so that the safety paths run under load.
pytestmark = [pytest.mark.hil, pytest.mark.realtime]

# Generous per-request timeout: the suite shares 2 cores with FMU builds.
URL_OPTIONS = "&timeout_s=0.5"
RUN_S = 6.0


def _start_run(emulator, out: Path, url_options: str = URL_OPTIONS,
               servo_options: str = "") -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "featherstar", "run", "testbed", "--quiet", "--no-figure",
         "--out", str(out),
         "--hardware", f"servo={emulator.servo_url}{url_options}{servo_options}",
         "--hardware", f"loadcell={emulator.loadcell_url}{url_options}",
         "--set", "master.periods=4", "--set", "metrics.settle_periods=1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _setpoint_deg(port: int) -> float | None:
    """The servo's setpoint register read back from the emulator (None if it does not answer)."""
    sp = load_servo_map("servo-default").setpoint
    with ModbusTcpClient("127.0.0.1", port=port, timeout=1.0, retries=0) as client:
        reply = client.read_holding_registers(sp.address, count=2, device_id=SERVO_UNIT)
        if reply.isError():
            return None
        return decode_value(sp, reply.registers)


def _wait_until_moving(emulator, run: subprocess.Popen, timeout_s: float = 60.0) -> None:
    """Block until the run commands the servo away from 0 (start-up is over)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert run.poll() is None, f"the run ended early: {run.communicate()}"
        value = _setpoint_deg(emulator.port)
        if value is not None and abs(value) > 1.0:
            time.sleep(0.5)    # well inside the run, not on its first step
            return
        time.sleep(0.05)
    pytest.fail("the run never moved the servo")


def _finish(run: subprocess.Popen) -> tuple[int, str]:
    _, err = run.communicate(timeout=90)
    lines = [ln for ln in err.splitlines() if ln.startswith("featherstar:")]
    assert len(lines) == 1, err   # exactly one line says why the run stopped
    return run.returncode, lines[0]


def _assert_partial_data_and_safe_servo(out: Path, port: int) -> dict:
    summary = json.loads((out / "summary.json").read_text())
    rows = (out / "results.csv").read_text().splitlines()
    # a few hundred ms of the run at least (46 rows under two busy processes: the master runs
    # late steps back to back, so run time lags the wall)
    assert "loadcell_hw.thrust_N" in rows[0] and len(rows) > 10
    assert summary["complete"] is False
    assert summary["safe_position_confirmed"] == {"servo": True}
    assert _setpoint_deg(port) == pytest.approx(0.0, abs=0.01)
    return summary


@pytest.mark.parametrize("signame, status", [("SIGTERM", 143), ("SIGINT", 130)])
def test_a_signal_to_the_run_stops_it_safely_and_keeps_the_data(tmp_path, signame, status):
    with spawn_emulator(plant="flat-plate", seed=1) as emulator:
        run = _start_run(emulator, tmp_path)
        try:
            _wait_until_moving(emulator, run)
            run.send_signal(getattr(signal, signame))
            code, line = _finish(run)
        finally:
            run.kill()
        assert code == status
        assert f"interrupted by {signame}" in line and "partial results" in line
        summary = _assert_partial_data_and_safe_servo(tmp_path, emulator.port)
        assert summary["failed_block"] == "master"
        assert 0.0 < summary["failed_at_s"] < RUN_S


def test_a_frozen_device_stops_the_run_and_the_servo_is_made_safe_once_it_wakes(tmp_path):
    with spawn_emulator(plant="flat-plate", seed=1) as emulator:
        run = _start_run(emulator, tmp_path)
        try:
            _wait_until_moving(emulator, run)
            os.kill(emulator.proc.pid, signal.SIGSTOP)
            time.sleep(1.0)
            os.kill(emulator.proc.pid, signal.SIGCONT)
            code, line = _finish(run)
        finally:
            os.kill(emulator.proc.pid, signal.SIGCONT)
            run.kill()
        assert code == 2
        assert "timeout" in line and "partial results" in line
        summary = _assert_partial_data_and_safe_servo(tmp_path, emulator.port)
        assert summary["failed_block"] in ("servo", "loadcell_hw")
        assert "timeout" in summary["error"]


def test_a_device_killed_and_restarted_is_recovered_but_its_periods_are_not_trusted(tmp_path):
    emulator = spawn_emulator(plant="flat-plate", seed=1)
    port = emulator.port
    run = _start_run(emulator, tmp_path, URL_OPTIONS + "&reconnect_s=20")
    restarted = None
    try:
        _wait_until_moving(emulator, run)
        emulator.kill()
        restarted = spawn_emulator(port=port, plant="flat-plate", seed=2)
        code, line = _finish(run)
    finally:
        run.kill()
        emulator.stop()
    try:
        # The run recovered and finished, but the load cell may have lost its tare: the periods
        # from the reconnect on are excluded and too few valid ones are left.
        assert code == 2 and "run incomplete" in line
        summary = _assert_partial_data_and_safe_servo(tmp_path, port)
        assert "error" not in summary and summary["reconnects"] >= 1
        invalid = summary["validity"]["invalid_periods"]
        assert any("tare unknown" in r for p in invalid for r in p["reasons"])
        assert summary["validity"]["valid_periods"] < summary["validity"]["needed_valid_periods"]
        assert summary["thrust_ratio_all_periods"] is not None
    finally:
        restarted.stop()


# SIGINT takes the same handler (tests/integration/test_hil_signals.py); one real run suffices.
@pytest.mark.parametrize("signame, status", [("SIGTERM", 143)])
def test_a_signal_during_the_safe_stop_after_a_fault_is_deferred_until_it_is_done(
        tmp_path, signame, status):
    """The device freezes, the run faults and retries the safe position; a signal (two, in
    fact) arrives during that retry. The retry must not be cut short: once the device wakes it
    is made safe, the partial data are written, and the exit status is the signal's."""
    with spawn_emulator(plant="flat-plate", seed=1) as emulator:
        run = _start_run(emulator, tmp_path, servo_options="&safe_timeout_s=30")
        try:
            _wait_until_moving(emulator, run)
            os.kill(emulator.proc.pid, signal.SIGSTOP)
            time.sleep(2.0)           # the 0.5 s timeout has fired: the safe stop is retrying
            assert run.poll() is None
            run.send_signal(getattr(signal, signame))
            time.sleep(0.3)
            run.send_signal(getattr(signal, signame))
            time.sleep(0.5)
            assert run.poll() is None, "the signal ended the process inside the safe stop"
            os.kill(emulator.proc.pid, signal.SIGCONT)
            _, err = run.communicate(timeout=90)
        finally:
            os.kill(emulator.proc.pid, signal.SIGCONT)
            run.kill()
        assert run.returncode == status, err
        line = next(ln for ln in err.splitlines() if ln.startswith("featherstar: error:"))
        assert "timeout" in line and "partial results" in line
        assert f"{signame} received during the safe stop" in line
        summary = _assert_partial_data_and_safe_servo(tmp_path, emulator.port)
        assert summary["failed_block"] in ("servo", "loadcell_hw")


def test_a_device_restart_behind_a_gateway_that_keeps_the_connection_is_not_a_result(tmp_path):
    """kill -USR1: both emulated devices restart, their TCP connections kept (a gateway in
    front of an RS-485 line). No reconnect shows it; the boot id does: the load cell's tare is
    unknown from then on, so the run cannot end `complete` on those data."""
    with spawn_emulator(plant="flat-plate", seed=1) as emulator:
        run = _start_run(emulator, tmp_path)
        try:
            _wait_until_moving(emulator, run)
            emulator.reboot()
            code, line = _finish(run)
        finally:
            run.kill()
        assert code == 2 and "run incomplete" in line
        summary = _assert_partial_data_and_safe_servo(tmp_path, emulator.port)
        assert summary["reconnects"] == 0       # the gateway kept the connection
        restarts = [e for e in summary["hardware_events"] if e["kind"] == "restart"]
        assert {e["device"] for e in restarts} == {"servo", "loadcell_hw"}
        assert any(e.get("tare_unknown") for e in restarts if e["device"] == "loadcell_hw")
        invalid = summary["validity"]["invalid_periods"]
        assert invalid and all(any("restarted" in r for r in p["reasons"]) for p in invalid)


def _position_deg(port: int) -> float | None:
    """The servo's read-back angle from the emulator (None if it does not answer)."""
    field = load_servo_map("servo-default").position
    with ModbusTcpClient("127.0.0.1", port=port, timeout=1.0, retries=0) as client:
        reply = client.read_holding_registers(field.address, count=2, device_id=SERVO_UNIT)
        return None if reply.isError() else decode_value(field, reply.registers)


def test_a_client_killed_with_sigkill_mid_stroke_leaves_the_servo_to_its_watchdog(tmp_path):
    """No client code runs after kill -9: the device's own watchdog (servo-default: 500 ms
    without a request) brings the servo to its safe position and holds it there."""
    with spawn_emulator(plant="flat-plate", seed=1) as emulator:
        run = _start_run(emulator, tmp_path)
        try:
            _wait_until_moving(emulator, run)
            deadline = time.monotonic() + 10.0
            while abs(_position_deg(emulator.port) or 0.0) < 15.0:
                assert time.monotonic() < deadline, "the stroke never left the centre"
            run.kill()
            run.wait(10)
            angle_at_kill = _position_deg(emulator.port)
            # the 0.5 s watchdog, then the travel back: waited for (a loaded PC gives the
            # emulator its CPU late), not slept on
            deadline = time.monotonic() + 15.0
            while abs(_position_deg(emulator.port) or 90.0) > 0.5 and time.monotonic() < deadline:
                time.sleep(0.05)
            settled = []
            for _ in range(3):      # safe, and held there (not a stroke passing 0)
                settled.append(_position_deg(emulator.port))
                time.sleep(0.25)
        finally:
            run.kill()
        assert run.returncode == -signal.SIGKILL
        assert abs(angle_at_kill) > 10.0
        assert settled == pytest.approx([0.0] * 3, abs=0.5), (angle_at_kill, settled)
