"""The testbed scene with the load cell and the servo swapped for Modbus devices: a real pymodbus
emulator on an ephemeral loopback port running the same servo and feather FMUs in real time."""
from __future__ import annotations

import json
import subprocess
import sys
import threading

import numpy as np
import pytest
from featherstar.cosim.errors import SceneError, StepError
from featherstar.cosim.scenes import load_scene
from featherstar.cosim.swimmer.run import run_scene
from featherstar.hil.emulator import spawn_emulator
from featherstar.hil.hardware import parse_hardware, with_hardware

pytestmark = pytest.mark.hil

# Real time: three periods of the plain feather, whose motion is periodic (no flap chaos), so
# the hardware run and the simulation can be compared period for period.
OVERRIDES = {"feather.morphology": "plain", "master.periods": 3, "metrics.settle_periods": 1}
EMULATOR = dict(plant="fmu", morphology="plain", noise_N=0.0, seed=1, start_timeout_s=180.0)


def _hardware_scene(emulator, slots=("servo", "loadcell")):
    # A dead device never acknowledges the safe position: do not wait the default 5 s for it.
    urls = {"servo": emulator.servo_url + "&safe_timeout_s=0.5", "loadcell": emulator.loadcell_url}
    return with_hardware(load_scene("testbed"), {slot: urls[slot] for slot in slots})


def test_testbed_with_hardware_matches_the_simulation():
    simulated = run_scene("testbed", OVERRIDES)
    emulator = spawn_emulator(**EMULATOR)
    try:
        result = run_scene(_hardware_scene(emulator), OVERRIDES)
    finally:
        emulator.stop()
    hardware = result.summary
    # Stated tolerance: the hardware loop runs at 250 Hz with zero-order-hold setpoints, a Modbus
    # round trip of lag and 4 ms samples of a signal with ~100 Hz chain modes; a few mN of offset
    # moves the plain feather's TR (thrust swings ±0.5 N around a mean of a few mN) by ~0.1 each.
    # Stated tolerance: TR within 0.3 (chordwise vs plain differ by ~2), swing within 15 %.
    assert hardware["thrust_ratio"] == pytest.approx(simulated.summary["thrust_ratio"], abs=0.3)
    swing_hw = np.ptp(result["loadcell_hw.thrust_N"])
    swing_sim = np.ptp(simulated["feather.thrust_N"])
    assert swing_hw == pytest.approx(swing_sim, rel=0.15)
    assert hardware["stats"]["deadline_misses"] < 0.2 * hardware["stats"]["macro_steps"]


def test_killed_device_stops_the_run_and_keeps_what_was_recorded(tmp_path):
    emulator = spawn_emulator(**EMULATOR)
    killer = threading.Timer(1.5, emulator.kill)
    killer.start()
    try:
        with pytest.raises(StepError) as info:
            run_scene(_hardware_scene(emulator), OVERRIDES)
    finally:
        killer.cancel()
        emulator.stop()
    error = info.value
    assert error.block in ("servo", "loadcell_hw")
    assert 1.0 < error.t_s < 4.5
    partial = error.partial
    assert partial is not None and not partial.complete
    assert 100 < len(partial.time) and partial.time[-1] <= error.t_s + 1e-9
    assert partial.summary["failed_block"] == error.block


def test_cli_writes_partial_results_and_the_fault_when_the_device_dies(tmp_path):
    emulator = spawn_emulator(**EMULATOR)
    # The CLI process needs a few seconds to start and load its FMUs before it runs.
    killer = threading.Timer(7.0, emulator.kill)
    killer.start()
    try:
        done = subprocess.run(
            [sys.executable, "-m", "featherstar", "run", "testbed", "--quiet", "--no-figure", "--out", str(tmp_path),
             "--hardware", f"servo={emulator.servo_url}&safe_timeout_s=0.5", "--hardware", f"loadcell={emulator.loadcell_url}",
             "--set", "feather.morphology=plain", "--set", "master.periods=8"],
            capture_output=True, text=True, timeout=120)
    finally:
        killer.cancel()
        emulator.stop()
    assert done.returncode == 2
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["failed_block"] in ("servo", "loadcell_hw") and "error" in summary
    # The device is gone for good: the safe position cannot be confirmed, and the one line says so.
    assert summary["safe_position_confirmed"] == {"servo": False}
    line = [ln for ln in done.stderr.splitlines() if ln.startswith("featherstar:")]
    assert len(line) == 1 and "servo did not acknowledge its safe position" in line[0]
    rows = (tmp_path / "results.csv").read_text().splitlines()
    assert len(rows) > 100 and "loadcell_hw.thrust_N" in rows[0]


@pytest.mark.parametrize("item", ["servo", "pump=modbus-tcp://x", "servo=", "loadcell"])
def test_bad_hardware_option_is_refused(item):
    with pytest.raises(SceneError, match="--hardware"):
        parse_hardware([item])


def test_realtime_needs_weak_coupling():
    scene = with_hardware(load_scene("testbed"), {"servo": "modbus-tcp://127.0.0.1:1?unit=2"})
    with pytest.raises(SceneError, match="realtime"):
        run_scene(scene, {"master.coupling": "strong"})
