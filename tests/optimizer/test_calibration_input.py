"""Bad input to `featherstar calibrate` and to `optimize --prior`: refused with one clear line,
before any simulation runs."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from featherstar.optimizer.bayes import optimize
from featherstar.optimizer.bench.sim_prior import SimPrior, study_morphology
from featherstar.optimizer.calibration.fit import calibrate
from featherstar.optimizer.calibration.recordings import read_recording
from featherstar.optimizer.cli import main as optimizer_main
from featherstar.optimizer.errors import OptimizerError
from featherstar.optimizer.evaluation import MeasurementPlan
from featherstar.optimizer.loadcell import LoadCell
from featherstar.optimizer.space import stroke_space
from featherstar.optimizer.synthetic import SyntheticFeather


def _write_run(path, *, header="time [s],servo.angle_rad [rad],loadcell_hw.thrust_N [N]", angle_scale=1.0,
               thrust_scale=1.0, phase=0.0, time_scale=1.0):
    t = np.arange(0.0, 1.2, 0.004)
    angle = angle_scale * 0.5 * np.sin(2 * np.pi * t + phase)
    thrust = thrust_scale * 0.1 * np.cos(2 * np.pi * t)
    path.write_text(header + "\n" + "\n".join(f"{a:.6f},{b:.6f},{c:.6f}" for a, b, c in zip(t * time_scale, angle, thrust)) + "\n")
    return path


def _one_line_error(capsys, argv):
    assert optimizer_main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


def test_a_featherstar_run_csv_is_read_in_si_units(tmp_path):
    run = read_recording(_write_run(tmp_path / "a.csv"))
    assert run.units == ("s", "rad", "N") and run.time_s[0] == 0.0
    converted = read_recording(_write_run(tmp_path / "b.csv", header="t_ms,angle_deg,thrust_mN",
                                          angle_scale=180 / math.pi, thrust_scale=1e3, time_scale=1e3))
    assert np.allclose(converted.time_s, run.time_s, atol=1e-9)
    assert np.allclose(converted.angle_rad, run.angle_rad, atol=1e-5)
    assert np.allclose(converted.thrust_N, run.thrust_N, atol=1e-6)


def test_a_csv_without_the_needed_columns_is_refused(tmp_path, capsys):
    csv = _write_run(tmp_path / "a.csv", header="time [s],servo.angle_rad [rad],pressure [Pa]")
    err = _one_line_error(capsys, ["calibrate", str(csv), "--window-s", "1", "--out", str(tmp_path / "o")])
    assert "no thrust column" in err and "a.csv" in err


def test_runs_in_different_units_are_refused(tmp_path, capsys):
    a = _write_run(tmp_path / "a.csv")
    b = _write_run(tmp_path / "b.csv", header="time [s],servo.angle_rad [rad],loadcell_hw.thrust_N [mN]",
                   thrust_scale=1e3)
    err = _one_line_error(capsys, ["calibrate", str(a), str(b), "--window-s", "1", "--out", str(tmp_path / "o")])
    assert "same units" in err and "b.csv" in err


def test_runs_of_different_strokes_are_refused(tmp_path, capsys):
    a = _write_run(tmp_path / "a.csv")
    b = _write_run(tmp_path / "b.csv", phase=0.5)
    err = _one_line_error(capsys, ["calibrate", str(a), str(b), "--window-s", "1", "--out", str(tmp_path / "o")])
    assert "repeat one stroke" in err and "b.csv" in err


@pytest.mark.parametrize("fit, message", [
    ("drag_coeff=-1,3", "outside the physical range [0, 10]"),
    ("added_mass_scale=0.5,4", "outside the physical range [0, 3]"),
    ("hinge_stiffness_Nm_rad_m", "has no such coefficient"),   # a plain feather has no hinge
    ("oscillatory_drag", "a switch"),
])
def test_a_coefficient_range_outside_physics_is_refused(tmp_path, capsys, fit, message):
    a = _write_run(tmp_path / "a.csv")
    err = _one_line_error(capsys, ["calibrate", str(a), "--window-s", "1", "--set", "feather.morphology=plain",
                                   "--fit", fit, "--out", str(tmp_path / "o")])
    assert message in err


def test_calibrate_refuses_before_simulating(tmp_path):
    run = read_recording(_write_run(tmp_path / "a.csv"))
    with pytest.raises(OptimizerError, match="period of the runs is unknown"):
        calibrate([run], "testbed", {})
    with pytest.raises(OptimizerError, match="shorter than the fit window"):
        calibrate([run], "testbed", {}, window_s=5.0)


def _simulated_study(directory, morphology):
    space = stroke_space(1.5)
    plan = MeasurementPlan(load_cell=LoadCell(noise_sd_N=0.0), settle_periods=1, periods=1)
    optimize(SyntheticFeather(morphology=morphology), space, directory / "evaluations.jsonl", iterations=4, plan=plan,
             context={"scene": f"synthetic:{morphology}", "overrides": {}})
    return space


def test_a_prior_of_another_morphology_is_refused(tmp_path, capsys):
    space = _simulated_study(tmp_path / "sim", "spanwise")
    with pytest.raises(OptimizerError, match="optimized a spanwise feather, this study measures a chordwise"):
        SimPrior.load(tmp_path / "sim", feather={"morphology": "chordwise"}, space=space, maximize=True)
    err = _one_line_error(capsys, [
        "optimize", "testbed", "--out", str(tmp_path / "bench"), "--prior", str(tmp_path / "sim"),
        "--hardware", "servo=modbus-tcp://127.0.0.1:1?unit=2", "--hardware", "loadcell=modbus-tcp://127.0.0.1:1?unit=1"])
    assert "--prior" in err and "spanwise" in err and "chordwise (width_ratio 7.5)" in err


def test_a_prior_of_the_same_feather_gives_its_best_strokes_first(tmp_path):
    space = _simulated_study(tmp_path / "sim", "chordwise")
    prior = SimPrior.load(tmp_path / "sim", feather=study_morphology("synthetic:chordwise", {}), space=space,
                          maximize=True)
    points = prior.initial_points(space, 3, maximize=True)
    values = dict(zip([tuple(sorted(p.items())) for p in prior.points], prior.values))
    assert values[tuple(sorted(points[0].items()))] == max(prior.values)
    assert all(space.is_feasible(p) for p in points)
    with pytest.raises(OptimizerError, match="it maximized TR, this study minimizes it"):
        SimPrior.load(tmp_path / "sim", feather={"morphology": "chordwise"}, space=space, maximize=False)
    with pytest.raises(OptimizerError, match="period_s"):
        SimPrior.load(tmp_path / "sim", feather={"morphology": "chordwise"}, space=stroke_space(3.0), maximize=True)


@pytest.mark.parametrize("damage, message", [
    (lambda lines: lines + [b"\xff\xfe{}"], "not UTF-8"),
    (lambda lines: lines + [lines[1]], "repeats the evaluation index 0"),
    (lambda lines: lines + [b"[1, 2]"], "not a log record"),
    (lambda lines: [lines[0], lines[1].replace(b'"thrust_ratio": ', b'"thrust_ratio": 1')] + lines[2:], "digest"),
])
def test_a_damaged_prior_log_is_one_line(tmp_path, damage, message):
    space = _simulated_study(tmp_path / "sim", "chordwise")
    log = tmp_path / "sim" / "evaluations.jsonl"
    log.write_bytes(b"\n".join(damage(log.read_bytes().splitlines())) + b"\n")
    with pytest.raises(OptimizerError, match=message) as refused:
        SimPrior.load(tmp_path / "sim", feather={"morphology": "chordwise"}, space=space, maximize=True)
    assert "\n" not in str(refused.value) and str(refused.value).startswith("--prior")


def test_calibration_recovers_coefficients_from_simulated_recordings(tmp_path):
    """The fit without real time: recordings as the emulator's plant would serve them (servo and
    feather strongly coupled, read every 4 ms, angle in 0.01°, 5 mN noise), so this runs on a
    machine too loaded for the emulator tests (tests/optimizer/test_calibration.py)."""
    from featherstar.cosim.swimmer.run import run_scene
    from featherstar.optimizer.calibration.recordings import Recording

    hidden = {"oscillatory_drag": 0.0, "drag_coeff": 1.56, "added_mass_scale": 0.85}
    result = run_scene("testbed", {"feather.morphology": "plain", "controller.period_s": 1.0, "master.t_end_s": 1.2,
                                   **{f"feather.{k}": v for k, v in hidden.items()}},
                       outputs=["feather.thrust_N", "servo.angle_rad"])
    rng = np.random.default_rng(1)
    t = result.time[::4]
    angle = np.round(np.degrees(result["servo.angle_rad"][::4]), 2) * math.pi / 180
    runs = [Recording(f"run{k}", t, angle, result["feather.thrust_N"][::4] + rng.normal(0, 0.005, len(t)),
                      ("s", "rad", "N"), 1.0) for k in range(3)]
    calibration = calibrate(runs, "testbed", {"feather.morphology": "plain"},
                            {"drag_coeff": None, "added_mass_scale": None}, window_s=1.0, thrust_samples="instant")
    for name in ("drag_coeff", "added_mass_scale"):
        assert calibration.values[name] == pytest.approx(hidden[name], rel=0.15), calibration.values
        assert 0 < calibration.sd[name] < 0.1 * calibration.values[name]
    assert calibration.parameter_set()["feather.oscillatory_drag"] == 0.0
    assert calibration.r_squared > 0.99

    # The parameter set, as --set arguments and as a scene's feather parameters line.
    from featherstar.cosim.scenes import load_scene
    from featherstar.optimizer.calibration.cli import write_calibration
    from featherstar.optimizer.calibration.forms import FormChoice, FormFit

    fit = FormFit("none", calibration, 0.003, {}, np.zeros(3), calibration.measured_N.size, 1e-3, {}, 80)
    paths = write_calibration([fit], FormChoice("none", ("none",), "the only form"), tmp_path / "cal",
                              runs=["run0", "run1", "run2"], scene="testbed", overrides={"feather.morphology": "plain"})
    assert (tmp_path / "cal" / "set.txt").read_text().startswith(
        "--set feather.wake=none --set feather.oscillatory_drag=0 --set feather.drag_coeff=")
    line = next(ln for ln in paths[2].read_text().splitlines() if ln.startswith("parameters"))
    scene_text = Path(load_scene("testbed").source).read_text()
    scene_text = "\n".join(line if ln.startswith("parameters = {") else ln for ln in scene_text.splitlines())
    (tmp_path / "calibrated.toml").write_text(scene_text)
    feather = load_scene(tmp_path / "calibrated.toml").to_dict()["blocks"]["feather"]["parameters"]
    assert feather["drag_coeff"] == pytest.approx(calibration.values["drag_coeff"], rel=1e-5)
    assert feather["oscillatory_drag"] == 0


def test_one_absurd_sample_is_refused_and_nothing_is_written(tmp_path, capsys):
    run = _write_run(tmp_path / "run.csv")
    lines = run.read_text().splitlines()
    t, angle, _ = lines[40].split(",")
    lines[40] = f"{t},{angle},1e300"   # one corrupt load-cell sample
    run.write_text("\n".join(lines) + "\n")
    out = tmp_path / "cal"
    err = _one_line_error(capsys, ["calibrate", str(run), str(run), "--window-s", "1", "--out", str(out),
                                   "--set", "feather.morphology=plain", "--forms", "none", "-q"])
    assert "1e+300 N" in err and "cannot be fitted" in err
    assert not out.exists()


def test_a_fit_that_is_not_finite_or_did_not_converge_is_no_calibration():
    from dataclasses import replace

    from featherstar.optimizer.calibration.fit import Calibration, Coefficient

    good = Calibration((Coefficient("drag_coeff", 0.1, 10.0, 1.0, "1"),), {"drag_coeff": 1.5}, {"drag_coeff": 0.01},
                       [[1.0]], {}, 0.002, 0.99, {}, 1.0, 20, 1.0, np.zeros(1), np.zeros((1, 1)), np.zeros((1, 1)))
    assert good.failure() is None
    assert "rms residual inf" in replace(good, rms_residual_N=math.inf).failure()
    assert "R² nan" in replace(good, r_squared=math.nan).failure()
    assert "drag_coeff sd inf" in replace(good, sd={"drag_coeff": math.inf}).failure()
    assert "did not converge" in replace(good, converged=False, solver_message="max_nfev").failure()


@pytest.mark.parametrize("content", [b"time,angle,thrust\n0,\xff\xfe,1\n", b"\xff\xfetime,angle\n", b"t,a\x00,f\n1,2,3\n"])
def test_a_recording_that_is_not_utf8_text_is_one_line(tmp_path, capsys, content):
    run = tmp_path / "run.csv"
    run.write_bytes(content)
    err = _one_line_error(capsys, ["calibrate", str(run), "--window-s", "1", "--out", str(tmp_path / "cal")])
    assert str(run) in err


def test_a_damaged_summary_beside_a_recording_is_one_line(tmp_path, capsys):
    run = _write_run(tmp_path / "run.csv")
    (tmp_path / "summary.json").write_bytes(b"\xff{")
    err = _one_line_error(capsys, ["calibrate", str(run), "--out", str(tmp_path / "cal")])
    assert "summary.json" in err


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(at=st.integers(0, 10**6), garbage=st.binary(min_size=1, max_size=6), cut=st.integers(0, 10**6))
def test_a_damaged_recording_is_read_or_refused_with_one_line(tmp_path, at, garbage, cut):
    """Bytes inserted anywhere and the file cut anywhere: a Recording, or an OptimizerError of one
    line naming the file; never another exception."""
    good = _write_run(tmp_path / "good.csv").read_bytes()
    position, end = at % len(good), cut % (len(good) + 1)
    damaged = tmp_path / "damaged.csv"
    damaged.write_bytes((good[:position] + garbage + good[position:])[:max(end, position + len(garbage))])
    try:
        recording = read_recording(damaged)
    except OptimizerError as exc:
        assert "\n" not in str(exc) and str(damaged) in str(exc)
    else:
        assert len(recording.time_s) >= 8 and np.all(np.isfinite(recording.thrust_N))


def test_every_feather_build_option_reaches_the_calibrated_model():
    """A scene calibrated with --set feather.wake=self (or a drag rule) is fitted with that model,
    not silently with the defaults (every catalog build option is passed on)."""
    from featherstar.fmu_src.catalog import build_options
    from featherstar.optimizer.calibration.fit import feather_block, feather_model

    block = feather_block("testbed")
    assert {"wake", "drag_points", "n_units"} <= set(build_options("feather"))
    model = feather_model(block, {"feather.morphology": "plain", "feather.wake": "self", "feather.drag_points": "3",
                                  "feather.n_units": "4"})
    assert dict(model.options)["wake"] == "self" and dict(model.options)["drag_points"] == 3
    assert dict(model.options)["n_units"] == 4
    assert "wake_drag_coeff" in {p.name for p in model.parameters}
