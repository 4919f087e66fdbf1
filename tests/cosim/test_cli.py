"""`featherstar run` and `featherstar scenes`."""
from __future__ import annotations

import csv
import json

from featherstar.app import main


def test_scenes_lists_shipped_scenes(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    for name in ("testbed", "robot", "kinematic"):
        assert any(line.startswith(name) and len(line.split(None, 1)) == 2 for line in out.splitlines())


def test_run_writes_summary_results_and_figure(tmp_path, capsys):
    out = tmp_path / "run"
    # one or more overrides per --set, as many --set as wanted
    rc = main(["run", "testbed", "--set", "feather.morphology=plain", "master.periods=2",
               "--set", "metrics.settle_periods=1", "--set", "controller.t_up_s=0.3", "master.coupling=strong",
               "--out", str(out), "-q"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "thrust ratio TR" in printed and "mean thrust" in printed
    summary = json.loads((out / "summary.json").read_text())
    for key in ("thrust_ratio", "mean_thrust_N", "wall_time_s"):
        assert isinstance(summary[key], float)
    assert summary["complete"] is True
    assert summary["info"]["overrides"]["controller.t_up_s"] == "0.3"
    assert summary["info"]["overrides"]["master.periods"] == "2"
    with open(out / "results.csv") as fh:
        rows = list(csv.reader(fh))
    assert rows[0][0] == "time [s]" and "feather.thrust_N [N]" in rows[0] and "servo.angle_rad [rad]" in rows[0]
    assert len(rows) == 3101 + 1  # 2 periods of 1.55 s at 1 ms, plus the header
    assert (out / "thrust.png").stat().st_size > 10_000


def test_scene_error_is_one_line_exit_2(capsys):
    rc = main(["run", "testbed", "--set", "feather.bogus=1", "--set", "master.coupling=sideways", "-q"])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("featherstar: error: scene 'testbed'")
    assert "bogus" in err[0] and "sideways" in err[0]
    assert main(["run", "no-such-scene", "-q"]) == 2
    assert "no scene 'no-such-scene'" in capsys.readouterr().err


def test_bad_set_syntax(capsys):
    assert main(["run", "testbed", "--set", "feather.width_ratio", "-q"]) == 2
    assert "BLOCK.PARAM=VALUE" in capsys.readouterr().err
