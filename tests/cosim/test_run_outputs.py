"""Results that check their own preconditions (issue 23): each metric states what it needs, the
summary is complete only when every need holds, and `featherstar run` clears an earlier run's
outputs before it starts, writes the results before the figure and survives a failing figure."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from featherstar.cosim.swimmer import report
from featherstar.cosim.swimmer.metrics import failed_preconditions, judge_valid_periods, scene_metrics
from featherstar.cosim.swimmer.run import run_scene
from featherstar.cosim.swimmer.validity import apply_validity
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from featherstar.app import main

PERIOD_S = 1.0
FAST = {"master.backend": "casadi", "feather.morphology": "plain", "master.periods": "2",
        "metrics.settle_periods": "1"}
FAST_ARGS = [item for k, v in FAST.items() for item in ("--set", f"{k}={v}")]


def _spec(**kw):
    return SimpleNamespace(thrust="f.thrust_N", position="", speed="", settle_periods=1.0, **kw)


def _metrics(t, thrust, period=PERIOD_S, settle=1.0):
    spec = _spec()
    spec.settle_periods = settle
    return scene_metrics(spec, period, t, {"f.thrust_N": thrust})


def _grid(t_end_s=4.0, step_s=1e-3):
    return np.arange(0.0, t_end_s + step_s / 2, step_s)


def test_a_clean_run_meets_every_precondition():
    t = _grid()
    out = _metrics(t, np.sin(2 * np.pi * t) + 0.2)
    assert failed_preconditions(out) == {}
    assert set(out["preconditions"]) == {"period_known", "whole_period_in_window", "samples_per_period",
                                         "finite_thrust", "negative_impulse", "finite_thrust_metrics"}
    assert out["periods_used"] == 3 and math.isfinite(out["thrust_ratio"])


def test_a_period_too_short_for_the_sampling_is_a_failed_precondition():
    t = _grid(step_s=1e-2)
    out = _metrics(t, np.sin(2 * np.pi * t / 0.05), period=0.05)   # 5 samples per period
    failed = failed_preconditions(out)
    assert list(failed) == ["samples_per_period"]
    assert "spans 5 samples" in failed["samples_per_period"]


def test_the_finding_period_1e9_gives_no_complete_infinite_tr():
    # metrics.period_s = 1e-9 gave TR = inf with complete: true (issue 23)
    t = _grid()
    out = _metrics(t, np.sin(2 * np.pi * t), period=1e-9)
    failed = failed_preconditions(out)
    assert "samples_per_period" in failed


def test_no_whole_period_in_the_window_is_a_failed_precondition():
    t = _grid(t_end_s=1.8)
    out = _metrics(t, np.sin(2 * np.pi * t))
    assert out["periods_used"] == 0
    assert "holds no whole period of 1 s after settle_periods = 1" in failed_preconditions(out)["whole_period_in_window"]


def test_no_period_at_all_is_a_failed_precondition():
    t = _grid()
    out = _metrics(t, np.sin(2 * np.pi * t), period=None)
    assert "period_known" in failed_preconditions(out)


@pytest.mark.parametrize("where_s, fails", [(2.5, True), (0.5, False), (3.0005, True)])
def test_nan_in_the_thrust_fails_only_inside_the_window(where_s, fails):
    t = _grid()
    thrust = np.sin(2 * np.pi * t)
    thrust[int(round(where_s / 1e-3))] = np.nan
    failed = failed_preconditions(_metrics(t, thrust))
    assert ("finite_thrust" in failed) is fails
    if fails:
        assert f"first at t = {t[int(round(where_s / 1e-3))]:.6g} s" in failed["finite_thrust"]
        assert "finite_thrust_metrics" in failed   # the NaN reaches TR and the mean


def test_thrust_that_never_turns_negative_leaves_tr_undefined():
    t = _grid()
    failed = failed_preconditions(_metrics(t, 1.0 + np.sin(2 * np.pi * t) ** 2))
    assert "negative_impulse" in failed and "finite_thrust_metrics" in failed


@settings(max_examples=60, deadline=None)
@given(st.floats(1e-9, 10.0), st.floats(0.0, 5.0), st.floats(0.5, 8.0), st.sampled_from([1e-3, 1e-2, 0.1]),
       st.booleans())
def test_complete_only_when_tr_is_a_finite_number_over_whole_well_sampled_periods(period, settle, t_end, step,
                                                                                  nan):
    t = _grid(t_end, step)
    thrust = np.sin(2 * np.pi * t / period) + 0.1
    if nan:
        thrust[len(t) // 2:] = np.nan
    out = _metrics(t, thrust, period=period, settle=settle)
    if not failed_preconditions(out):
        assert out["periods_used"] >= 1 and period / step >= 20
        assert math.isfinite(out["thrust_ratio"]) and math.isfinite(out["mean_thrust_N"])
        a, b = out["window_s"]
        assert np.all(np.isfinite(thrust[(t >= a) & (t <= b)]))


def test_a_hardware_run_judges_finiteness_over_its_valid_periods_only():
    t = _grid(5.0, 4e-3)
    thrust = np.sin(2 * np.pi * t) + 0.1
    thrust[(t > 2.2) & (t < 2.3)] = np.nan                  # a gap, inside period 1 of the window
    summary = _metrics(t, thrust)
    events = [{"t_s": 2.25, "kind": "gap", "device": "cell"}]
    trusted = apply_validity(summary, t, thrust, PERIOD_S, 4e-3, [], events)
    judge_valid_periods(summary, t, thrust, PERIOD_S, trusted)
    assert summary["validity"]["invalid_periods"][0]["period"] == 2
    assert failed_preconditions(summary) == {}               # the excluded period held the NaN
    thrust[(t > 3.5) & (t < 3.6)] = np.nan                   # now one in a valid period too
    summary = _metrics(t, thrust)
    trusted = apply_validity(summary, t, thrust, PERIOD_S, 4e-3, [], events)
    judge_valid_periods(summary, t, thrust, PERIOD_S, trusted)
    assert "finite_thrust" in failed_preconditions(summary)


def test_a_reconnect_that_loses_the_tare_is_named_as_a_failed_precondition():
    t = _grid(5.0, 4e-3)
    thrust = np.sin(2 * np.pi * t) + 0.1
    summary = _metrics(t, thrust)
    events = [{"t_s": 1.1, "kind": "reconnect", "device": "cell", "tare_unknown": True}]
    trusted = apply_validity(summary, t, thrust, PERIOD_S, 4e-3, [], events)
    judge_valid_periods(summary, t, thrust, PERIOD_S, trusted)
    assert not trusted and "only 0 of 4 periods are valid" in failed_preconditions(summary)["valid_periods"]


def test_an_api_run_with_too_few_samples_per_period_is_not_complete():
    result = run_scene("kinematic", {**FAST, "metrics.period_s": "0.01"})
    assert not result.complete
    assert result.summary["incomplete_reason"].startswith("samples_per_period: a period of 0.01 s spans 10")
    clean = run_scene("kinematic", FAST)
    assert clean.complete and "incomplete_reason" not in clean.summary


# --- featherstar run ---------------------------------------------------------------------------

def _stale(out):
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps({"complete": True, "thrust_ratio": 9.9}))
    (out / "results.csv").write_text("time [s]\n0\n")
    (out / "thrust.png").write_bytes(b"old")


def _one_error_line(capsys) -> str:
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("featherstar: error:"), err
    return err[0]


@pytest.mark.parametrize("argv", [
    ["--set", "master.atol=1"],                               # refused by the schema
    ["--set", "metrics.period_s=0.01"],                       # refused by the metric window check
    ["--set", "feather.nosuch=1"],                            # refused by the plan
])
def test_a_refused_run_leaves_no_stale_summary(tmp_path, capsys, argv):
    out = tmp_path / "out"
    _stale(out)
    assert main(["run", "kinematic", "-q", "--out", str(out), *FAST_ARGS, *argv]) == 2
    _one_error_line(capsys)
    assert not any((out / name).exists() for name in report.OUTPUT_FILES)


def test_an_unwritable_out_is_one_line_before_any_work(tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    assert main(["run", "kinematic", "-q", "--out", str(blocker / "out"), *FAST_ARGS]) == 2
    line = _one_error_line(capsys)
    assert f"--out {blocker / 'out'}: cannot write there" in line


def test_a_failing_figure_is_a_warning_and_the_results_are_kept(tmp_path, capsys, monkeypatch):
    def broken(result, path):
        raise RuntimeError("no display fonts")

    monkeypatch.setattr(report, "plot_run", broken)
    out = tmp_path / "out"
    _stale(out)
    assert main(["run", "kinematic", "-q", "--out", str(out), *FAST_ARGS]) == 0
    err = capsys.readouterr().err
    assert "featherstar: warning: figure not written: RuntimeError: no display fonts" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True and summary["thrust_ratio"] != 9.9
    assert "figure not written: RuntimeError: no display fonts" in summary["warnings"]
    assert len((out / "results.csv").read_text().splitlines()) > 1000
    assert not (out / "thrust.png").exists()                  # the stale figure is gone too
    assert not list(out.glob(".*.partial"))


def test_the_results_are_on_disk_before_the_figure_is_drawn(tmp_path, monkeypatch):
    out = tmp_path / "out"
    seen = {}

    def drawing(result, path):
        seen["files"] = sorted(p.name for p in out.iterdir())
        seen["complete"] = json.loads((out / "summary.json").read_text())["complete"]
        path.write_bytes(b"png")

    monkeypatch.setattr(report, "plot_run", drawing)
    assert main(["run", "kinematic", "-q", "--out", str(out), *FAST_ARGS]) == 0
    assert seen == {"files": ["results.csv", "summary.json"], "complete": True}
    assert (out / "thrust.png").read_bytes() == b"png"


MASTER_VALUES = {"master.rtol": ["1e-7", "1", "0", "x"], "master.atol": ["1e-9", "1", "-1"],
                 "master.periods": ["2.5", "1e9", "nan", "0"], "metrics.settle_periods": ["0", "1.5", "-1", "x"],
                 "metrics.period_s": ["1e-9", "0.5", "inf"], "master.coupling": ["jacobi", "jacobbi", "3"],
                 "controller.t_up_s": ["0.3", "-1", "x", "true"], "feather.width_ratio": ["5", "x", "1e9"]}


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.sampled_from(sorted(MASTER_VALUES)).flatmap(
    lambda k: st.tuples(st.just(k), st.sampled_from(MASTER_VALUES[k]))))
def test_the_command_runs_or_refuses_in_one_line(capsys, key_value):
    key, value = key_value
    capsys.readouterr()   # capsys is shared by the examples: start each from empty
    code = main(["run", "kinematic", "-q", "--no-figure", *FAST_ARGS, "--set", f"{key}={value}"])
    captured = capsys.readouterr()
    assert code in (0, 2)
    if code == 2:
        line = [ln for ln in captured.err.splitlines() if ln.strip()]
        assert len(line) == 1 and line[0].startswith("featherstar: error:"), line
        assert key.partition(".")[2] in line[0] or "incomplete" in line[0], line
    else:
        assert "thrust ratio TR" in captured.out


@pytest.mark.parametrize("edit, names", [
    (lambda text: text.replace(b'description = "Ideal', b'description = "\xff\xfeIdeal'), "not UTF-8 text (byte 0xff"),
    (lambda text: b"master = 3\n" + text.replace(b"[master]", b"[unused_master]"), "[master] must be a table"),
    (lambda text: text + b'\n[blocks.extra]\nkind = "gain"\ngain = [1, 2]\n', "extra.gain = [1, 2] must be a number"),
    (lambda text: text.replace(b"connections = [", b"connections = {}\nold_connections = ["),
     "connections = {} must be an array"),
])
def test_a_broken_scene_file_is_one_line_naming_file_and_key(tmp_path, capsys, edit, names):
    from featherstar.cosim.scenes import shipped_scenes

    file = tmp_path / "broken.toml"
    file.write_bytes(edit(shipped_scenes()["kinematic"].read_bytes()))
    assert main(["run", str(file), "-q", "--out", str(tmp_path / "out")]) == 2
    line = _one_error_line(capsys)
    assert str(file) in line and names in line
