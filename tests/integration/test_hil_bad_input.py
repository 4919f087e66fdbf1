"""Bad input to `featherstar run` is refused before any work: exit 2 and one line naming it."""
from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from featherstar.cosim.scenes import load_scene
from featherstar.hil.emulator import spawn_emulator
from featherstar.hil.hardware import split_url, with_hardware

from featherstar.app import main

HW = ["--hardware", "servo=modbus-tcp://127.0.0.1:1?unit=2",
      "--hardware", "loadcell=modbus-tcp://127.0.0.1:1?unit=1"]


def _refused(capsys, argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("featherstar: error:")
    return err[0]


def test_unwritable_out_is_refused_before_the_run(tmp_path, capsys):
    if os.geteuid() == 0:
        target = Path("/proc/featherstar-out/run")   # not even root may create it
    else:
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        target = locked / "run"
    line = _refused(capsys, ["run", "testbed", "--quiet", "--out", str(target)])
    assert f"--out {target}: cannot write there" in line


def test_out_that_is_a_file_is_refused_before_the_run(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    line = _refused(capsys, ["run", "testbed", "--quiet", "--out", str(blocker)])
    assert f"--out {blocker}" in line


@pytest.mark.parametrize("option, value", [("timeout_s", "0"), ("reconnect_s", "-1"),
                                           ("timeout_s", "nan"), ("reconnect_s", "soon")])
def test_bad_url_block_options_are_refused(capsys, option, value):
    argv = ["run", "testbed", "--quiet", "--hardware",
            f"servo=modbus-tcp://127.0.0.1:1?unit=2&{option}={value}"]
    line = _refused(capsys, argv)
    assert f"{option}={value!r}" in line and "positive number of seconds" in line


def test_url_block_options_reach_the_blocks():
    url, options = split_url("loadcell",
                             "modbus-tcp://127.0.0.1:5020?unit=1&timeout_s=0.2&reconnect_s=3")
    assert url == "modbus-tcp://127.0.0.1:5020?unit=1"
    assert options == {"timeout_s": 0.2, "reconnect_s": 3.0}
    scene = with_hardware(load_scene("testbed"), {"servo": "modbus-tcp://h:1?unit=2&safe_timeout_s=9",
                                                  "loadcell": "modbus-tcp://h:1?timeout_s=0.2"})
    blocks = scene.to_dict()["blocks"]
    assert blocks["servo"]["parameters"] == {"url": "modbus-tcp://h:1?unit=2", "safe_timeout_s": 9.0}
    assert blocks["loadcell_hw"]["parameters"] == {"url": "modbus-tcp://h:1", "timeout_s": 0.2}


def test_a_real_load_cell_on_a_simulated_servo_is_refused_by_name(capsys):
    line = _refused(capsys, ["run", "testbed", "--quiet", "--hardware",
                             "loadcell=modbus-tcp://127.0.0.1:1?unit=1"])
    assert "--hardware loadcell without --hardware servo" in line
    assert "--allow-unactuated-loadcell" in line


@pytest.mark.hil
def test_the_explicit_flag_runs_it_with_a_warning_in_the_summary(tmp_path, capsys):
    with spawn_emulator(plant="flat-plate", seed=1) as emulator:
        code = main(["run", "testbed", "--quiet", "--no-figure", "--out", str(tmp_path),
                     "--allow-unactuated-loadcell",
                     "--hardware", f"loadcell={emulator.loadcell_url}&timeout_s=0.5",
                     "--set", "master.periods=2", "--set", "metrics.settle_periods=0"])
    out = capsys.readouterr().out
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert any("nothing the run commands moves the feather" in w for w in summary["warnings"])
    assert "WARNING: loadcell_hw: the load cell is real but the servo is simulated" in out
    assert code in (0, 2) and summary["complete"] is (code == 0)


@pytest.mark.parametrize("value", ["false", "False", "no"])
def test_an_unpaced_hardware_run_is_refused(capsys, value):
    line = _refused(capsys, ["run", "testbed", "--quiet", *HW, "--set", f"master.realtime={value}"])
    assert "master.realtime" in line and "paced in real time" in line
