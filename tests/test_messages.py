"""What a newcomer reads (issue 27): progress on a cold FMU build, hints that speak of the key the
user set, notes only when asked, the stroke amplitude said as peak to peak, the optimizer saying
that its box excludes the baseline."""
from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from featherstar.app import main
from featherstar.cosim.errors import SceneError
from featherstar.fmu_src import build_progress, export
from featherstar.fmu_src.servo import servo_model


@pytest.fixture
def slow_build(tmp_path, monkeypatch):
    """build_fmu with an empty cache and a CasADi-free build that takes 0.3 s."""
    monkeypatch.setenv("FEATHERSTAR_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(build_progress, "TICK_S", 0.1)

    def fake_build(model, shell, work, fmi_version):
        time.sleep(0.3)
        path = work / f"{model.name}.fmu"
        path.write_bytes(b"not an fmu")
        return path

    monkeypatch.setattr(export, "_build", fake_build)
    build_progress.reset()   # whatever a command before this test left
    yield
    build_progress.reset()


def test_a_cold_build_says_what_n_of_m_and_how_long(slow_build, capsys):
    build_progress.number_builds(3)
    build_progress.next_block()
    build_progress.next_block()
    export.build_fmu(servo_model())
    err = capsys.readouterr().err
    assert "building FMU servo (2 of 3)" in err
    assert "still building FMU servo:" in err                  # the elapsed time while it runs
    assert "built FMU servo (2 of 3) in 0." in err
    export.build_fmu(servo_model())                           # cached now: nothing to say
    assert capsys.readouterr().err == ""


def test_quiet_keeps_one_line_with_the_duration(slow_build, capsys):
    build_progress.reset(quiet=True)
    export.build_fmu(servo_model())
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("featherstar: built FMU servo in 0.")


def test_featherstar_build_numbers_its_models(slow_build, capsys):
    assert main(["build", "servo", "robot", "-q"]) == 0
    err = capsys.readouterr().err
    assert "built FMU servo (1 of 2)" in err and "built FMU robot (2 of 2)" in err
    assert "building FMU" not in err                          # -q: only the lines with durations


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=st.sampled_from(["master.t_end_s", "master.periods"]), length=st.integers(1, 3))
def test_the_run_length_hint_names_the_key_the_user_set(key, length):
    """A settle time that leaves no period to measure: the hint names the length the user set."""
    from featherstar.cosim.swimmer.run import prepare

    value = 1.5 * length if key == "master.t_end_s" else length
    with pytest.raises(SceneError) as caught:
        prepare("testbed", {key: value, "metrics.settle_periods": length + 1}, strict_window=True)
    text = str(caught.value)
    assert f"{key} = {value:g}" in text
    other = "master.periods" if key == "master.t_end_s" else "master.t_end_s"
    assert other not in text


def _testbed_run(argv, capsys):
    assert main(["run", "testbed", "-q", "--no-figure", "--set", "master.periods=4", "metrics.settle_periods=2",
                 *argv]) == 0
    return capsys.readouterr().out


def test_the_run_says_peak_to_peak_and_keeps_routine_notes_for_verbose(capsys):
    out = _testbed_run(["controller.amplitude_deg=50"], capsys)
    assert "amplitude 50° peak to peak (±25°)" in out
    assert "note:" not in out                                 # the shared amplitude, every run
    verbose = _testbed_run(["-v"], capsys)
    assert "note: feather: stroke_amplitude_rad" in verbose


def test_the_scene_listing_says_peak_to_peak(capsys):
    assert main(["scenes", "testbed"]) == 0
    line = next(l for l in capsys.readouterr().out.splitlines() if "controller.amplitude_deg" in l)
    assert "peak to peak" in line and "+-30" in line


def test_a_box_without_the_baseline_is_said_at_start_and_at_a_losing_end(tmp_path, capsys, monkeypatch):
    """The default box excludes the paper's symmetric stroke: said when the study starts, in
    summary.json, and again when the study ends below the baseline."""
    from featherstar.optimizer import cli

    real = cli.run_study

    def losing(*args, **kwargs):
        summary = real(*args, **kwargs)
        summary["thrust_ratio"] = summary["baseline_thrust_ratio"] - 0.1
        return summary

    monkeypatch.setattr(cli, "run_study", losing)
    assert main(["optimize", "synthetic:plain", "--iterations", "4", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out.splitlines()
    said = [k for k, line in enumerate(out) if "the baseline lies outside the search box: log10_hold_move" in line]
    assert said and said[0] < 3, out[:4]                       # at the start
    assert any("the study ended below the baseline" in line for line in out[-3:])
    summary = json.loads((Path(tmp_path) / "summary.json").read_text())
    assert "log10_hold_move" in summary["baseline_outside_search_box"]


def test_a_box_holding_the_baseline_says_nothing():
    from featherstar.optimizer.space import ServoLimits, stroke_space
    from featherstar.optimizer.study import baseline_outside_box

    assert "ramps >= 0.317 s" in baseline_outside_box(stroke_space(1.5))
    assert baseline_outside_box(stroke_space(1.5, servo=ServoLimits(max_rate_rad_s=12.0))) is None
