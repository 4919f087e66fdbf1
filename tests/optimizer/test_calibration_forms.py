"""Model-form calibration (`featherstar calibrate`, featherstar.optimizer.calibration.forms): the
choice rule, the unidentified-coefficient flag, refused recordings.

The bench that checks the choice on the emulator's plant for every wake law is
bench/bench_model_form_calibration.py (minutes per case); these stay small: the rule on
constructed evidence, and one short real fit of a coefficient the recordings cannot identify."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from featherstar.cosim.swimmer.run import run_scene
from featherstar.optimizer.calibration.fit import Calibration, Coefficient, measured_thrust_N
from featherstar.optimizer.calibration.forms import (BIC_DECISIVE, TIE_SIGMAS, FormFit, choose, fit_window_s,
                                                     usable_recordings)
from featherstar.optimizer.errors import OptimizerError
from featherstar.optimizer.calibration.identify import unidentified
from featherstar.optimizer.calibration.recordings import Recording
from featherstar.optimizer.cli import main as optimizer_main


def _calibration(values, sd, correlation=None) -> Calibration:
    names = list(values)
    correlation = correlation or np.eye(len(names)).tolist()
    return Calibration(tuple(Coefficient(n, 0.0, 10.0, 1.0, "1") for n in names), dict(values), dict(sd), correlation,
                       {}, 0.002, 0.99, {}, 1.0, 20, 1.0, np.zeros(1), np.zeros((1, 1)), np.zeros((1, 1)))


def _form(name, held_out_squared, rss=1e-3, n=75, flagged=None) -> FormFit:
    squared = np.asarray(held_out_squared, dtype=float)
    return FormFit(name, _calibration({"drag_coeff": 1.5}, {"drag_coeff": 0.01}), float(np.sqrt(squared.mean())), {},
                   squared, n, rss, flagged or {}, 10)


def test_identification_flags_a_free_a_loose_and_a_traded_off_coefficient():
    assert unidentified(_calibration({"a": 1.0, "b": 2.0}, {"a": 0.01, "b": 0.1})) == {}
    free = unidentified(_calibration({"a": 1.0, "b": 2.0}, {"a": 0.01, "b": math.inf}))
    assert list(free) == ["b"] and "does not depend on it" in free["b"]
    loose = unidentified(_calibration({"a": 1.0}, {"a": 0.3}))
    assert "30% of its value" in loose["a"]
    traded = unidentified(_calibration({"a": 1.0, "b": 2.0}, {"a": 0.01, "b": 0.02}, [[1.0, -0.99], [-0.99, 1.0]]))
    assert set(traded) == {"a", "b"} and "correlation -0.990 with b" in traded["a"]


def test_the_form_with_clearly_lower_held_out_error_is_chosen():
    rng = np.random.default_rng(0)
    noise = rng.normal(0, 1e-3, 75) ** 2
    choice = choose([_form("none", noise + 4e-6), _form("plate", noise)])
    assert (choice.chosen, choice.status, choice.tied) == ("plate", "calibrated", ("plate",))


def test_forms_within_noise_are_undecided_unless_bic_decides():
    rng = np.random.default_rng(1)
    a, b = rng.normal(0, 1e-3, 75) ** 2, rng.normal(0, 1e-3, 75) ** 2
    undecided = choose([_form("none", a), _form("self", b)])
    assert undecided.chosen is None and undecided.status == "undecided" and set(undecided.tied) == {"none", "self"}
    # the same held-out errors, but one fits all runs with a clearly smaller RSS (BIC lower by > BIC_DECISIVE)
    decided = choose([_form("none", a, rss=1e-3), _form("self", b, rss=1e-3 * math.exp(-2 * BIC_DECISIVE / 75))])
    assert decided.chosen == "self" and "BIC tie-break" in decided.reason


def test_a_chosen_form_with_an_unidentified_coefficient_is_no_calibration():
    rng = np.random.default_rng(2)
    noise = rng.normal(0, 1e-3, 75) ** 2
    choice = choose([_form("none", noise + 4e-6), _form("plate", noise, flagged={"wake_forcing": "sd not finite"})])
    assert (choice.chosen, choice.status) == ("plate", "not identified") and "wake_forcing" in choice.reason


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(1e-7, 1e-4), min_size=2, max_size=4), st.lists(st.floats(0.5, 2.0), min_size=4, max_size=4),
       st.integers(0, 2**31))
def test_a_form_is_chosen_only_on_evidence_beyond_noise(scales, rss_factors, seed):
    """Whatever the evidence: a form left out of the tie is worse held out by more than
    TIE_SIGMAS standard errors; a form chosen over the best held-out one wins BIC by BIC_DECISIVE."""
    rng = np.random.default_rng(seed)
    forms = ["none", "relative", "self", "plate"][:len(scales)]
    fits = [_form(f, s * rng.chisquare(1, 60), rss=s * 60 * r) for f, s, r in zip(forms, scales, rss_factors)]
    choice = choose(fits)
    best = min(fits, key=lambda f: f.held_out_rms_N)
    for f in fits:
        d = f.held_out_squared_N2 - best.held_out_squared_N2
        beyond = d.mean() > TIE_SIGMAS * d.std(ddof=1) / math.sqrt(d.size) if f is not best else False
        assert (f.form in choice.tied) != beyond
    if choice.chosen not in (None, best.form):
        winner = next(f for f in fits if f.form == choice.chosen)
        assert all(winner.bic <= f.bic - BIC_DECISIVE for f in fits if f.form in choice.tied and f is not winner)
    if choice.chosen is None:
        tied = sorted(f.bic for f in fits if f.form in choice.tied)
        assert len(tied) > 1 and tied[1] - tied[0] < BIC_DECISIVE


def test_incomplete_and_short_recordings_are_refused_and_named():
    t = np.linspace(0, 1.2, 300)
    ok = Recording("ok", t, np.sin(t), np.cos(t), ("s", "rad", "N"), 1.0, True)
    stopped = Recording("stopped", t, np.sin(t), np.cos(t), ("s", "rad", "N"), 1.0, False, "servo: lag")
    short = Recording("short", t[:100], np.sin(t[:100]), np.cos(t[:100]), ("s", "rad", "N"), 1.0)
    kept, refused = usable_recordings([ok, stopped, short], 1.0)
    assert [r.source for r in kept] == ["ok"]
    assert refused[0] == {"run": "stopped", "reason": "incomplete run (servo: lag)"}
    assert refused[1]["run"] == "short" and "shorter than the fit window" in refused[1]["reason"]


def test_the_fit_window_is_seconds_or_whole_stroke_periods():
    t = np.linspace(0, 3.2, 641)
    runs = [Recording(f"r{k}", t, np.sin(t), np.cos(t), ("s", "rad", "N"), 1.5) for k in range(2)]
    assert fit_window_s(runs) == 1.5 and fit_window_s(runs, periods=2) == 3.0 and fit_window_s(runs, 0.7) == 0.7
    for kwargs, message in [({"window_s": 1.0, "periods": 2}, "give one"), ({"periods": 0}, "at least 1"),
                            ({"window_s": float("nan")}, "positive number")]:
        with pytest.raises(OptimizerError, match=message):
            fit_window_s(runs, **kwargs)
    unknown = [Recording("u", t, np.sin(t), np.cos(t), ("s", "rad", "N"), None)]
    with pytest.raises(OptimizerError, match="give --window-s"):
        fit_window_s(unknown, periods=3)
    # three periods of a 1.5 s stroke: a 3.2 s run is too short, and is refused by name
    kept, refused = usable_recordings(runs, fit_window_s(runs, periods=3))
    assert not kept and "shorter than the fit window (4.5 s)" in refused[0]["reason"]


def test_periods_and_window_are_refused_together_in_one_line(tmp_path, capsys):
    run = tmp_path / "a.csv"
    run.write_text("time [s],angle [rad],thrust [N]\n" + "\n".join(f"{k * 0.01},0,0" for k in range(120)) + "\n")
    for argv, message in [(["--periods", "2", "--window-s", "1"], "not allowed with argument"),
                          (["--periods", "0"], "at least 1 stroke period"), (["--periods", "1.5"], "whole number")]:
        with pytest.raises(SystemExit) as exit_:
            optimizer_main(["calibrate", str(run), str(run), "--out", str(tmp_path / "o"), *argv])
        assert exit_.value.code == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err, err


def _write_runs(tmp_path, n, *, complete=None):
    """n recordings of the plain feather's testbed stroke (simulated, 5 mN noise), as run directories."""
    result = run_scene("testbed", {"feather.morphology": "plain", "feather.oscillatory_drag": 0.0,
                                   "controller.period_s": 1.0, "master.t_end_s": 0.3},
                       outputs=["feather.thrust_N", "servo.angle_rad"])
    rng = np.random.default_rng(3)
    paths = []
    for k in range(n):
        run = tmp_path / f"run{k}"
        run.mkdir()
        thrust = result["feather.thrust_N"][::4] + rng.normal(0, 0.005, len(result.time[::4]))
        rows = "\n".join(f"{t:.6f},{a:.8f},{f:.8f}" for t, a, f in zip(result.time[::4], result["servo.angle_rad"][::4], thrust))
        (run / "results.csv").write_text("time [s],servo.angle_rad [rad],loadcell_hw.thrust_N [N]\n" + rows + "\n")
        if complete is not None:
            (run / "summary.json").write_text(json.dumps({"period_s": 1.0, "complete": complete[k],
                                                          **({} if complete[k] else {"incomplete_reason": "gap"})}))
        paths.append(run)
    return paths


def test_a_coefficient_the_recordings_cannot_identify_is_reported_not_identified(tmp_path, capsys):
    """stroke_amplitude_rad only sets the KC drag, which oscillatory_drag = 0 switches off (in the
    recorded plant too): the thrust does not depend on it, the fit still reaches a fine R², and
    calibrate says it is no calibration (exit 3, no set.txt) instead of writing it. The third run
    is incomplete: refused."""
    runs = _write_runs(tmp_path, 3, complete=[True, True, False])
    out = tmp_path / "cal"
    status = optimizer_main(["calibrate", *map(str, runs), "--window-s", "0.25", "--forms", "none", "--out", str(out),
                             "--set", "feather.morphology=plain", "feather.oscillatory_drag=0",
                             "--fit", "stroke_amplitude_rad=0.1,3", "--thrust-samples", "instant"])
    printed = capsys.readouterr().out
    assert status == 3
    assert f"refused {runs[2]}: incomplete run (gap)" in printed
    assert "NOT IDENTIFIED" in printed and "NOT A CALIBRATION (not identified)" in printed
    report = json.loads((out / "calibration.json").read_text())
    assert report["status"] == "not identified" and report["chosen_form"] == "none"
    coefficients = report["forms"]["none"]["coefficients"]
    assert coefficients["stroke_amplitude_rad"]["identified"] is False
    assert "does not depend on it" in coefficients["stroke_amplitude_rad"]["why_not"]
    assert report["forms"]["none"]["r_squared"] > 0.95
    assert report["refused_runs"] == [{"run": str(runs[2]), "reason": "incomplete run (gap)"}]
    assert not (out / "set.txt").exists() and not (out / "feather-parameters.toml").exists()


def test_the_forms_option_is_checked_before_any_simulation(tmp_path, capsys):
    run = tmp_path / "a.csv"
    run.write_text("time [s],angle [rad],thrust [N]\n" + "\n".join(f"{k * 0.01},0,0" for k in range(120)) + "\n")
    for argv, message in [(["--forms", "none,wakey"], "valid forms are none, relative, self, plate"),
                          (["--forms", "none", "--set", "feather.wake=self"], "both choose the model form"),
                          (["--set", "feather.wake=plat"], "valid forms are none, relative, self, plate")]:
        assert optimizer_main(["calibrate", str(run), str(run), "--window-s", "1", "--out", str(tmp_path / "o"), *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err, err


def test_an_interval_mean_thrust_sample_stands_for_its_intervals_middle():
    """The bench's load cell reports the mean force over the step before each stamp: a ramp
    F = t read so is t - dt/2 at each stamp, and is read back as the ramp itself."""
    dt = 0.005
    t = np.arange(1, 200) * dt
    mean_before = t - dt / 2    # the mean of F = t over [t - dt, t]
    ramp = Recording("ramp", t, np.zeros_like(t), mean_before, ("s", "rad", "N"), 1.0)
    grid = np.linspace(0.1, 0.9, 50)
    assert np.allclose(measured_thrust_N(ramp, grid, "interval-mean"), grid, atol=1e-12)
    assert np.allclose(measured_thrust_N(ramp, grid), grid - dt / 2, atol=1e-12)   # default: instant
