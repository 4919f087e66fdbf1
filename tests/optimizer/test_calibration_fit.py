"""The calibration's fit on three fixed real-time recordings of the emulator (no real time needed).

tests/optimizer/data/chordwise_realtime/run0-2: `featherstar run --hardware` output of the
chordwise feather on `featherstar emulate --plant fmu` with hidden drag_coeff 1.56 (constant
drag), added_mass_scale 0.85 and hinge_stiffness 0.02 N.m/rad/m, 200 Hz, recorded by
tests/optimizer/test_calibration.py during a CI run in which that test failed: every recording was
clean (no deadline miss, gap or lag), yet the least squares, started from the coarse scan's best
point, stopped at drag 2.43 (+56 %) with R² 0.984, where the fit near the true drag reaches R²
0.9987. The fine scan around the coarse best (featherstar.optimizer.calibration.fit) is what finds
that valley; this pins it on data that showed the failure, deterministically.
"""
from __future__ import annotations

from pathlib import Path

import pytest
from featherstar.optimizer.calibration.fit import calibrate
from featherstar.optimizer.calibration.recordings import read_recording

DATA = Path(__file__).parent / "data" / "chordwise_realtime"
HIDDEN = {"drag_coeff": 1.56, "added_mass_scale": 0.85, "hinge_stiffness_Nm_rad_m": 0.02}


def test_the_fit_finds_the_true_valley_from_recordings_where_the_coarse_start_misled_it():
    runs = [read_recording(DATA / f"run{k}") for k in range(3)]
    calibration = calibrate(runs, "testbed", {"feather.morphology": "chordwise"}, dict.fromkeys(HIDDEN),
                            window_s=1.0)
    for name, value in calibration.values.items():
        assert value == pytest.approx(HIDDEN[name], rel=0.15), (name, value)
    # The recordings predate the drag quadrature of issue 26 (drag on strips, 4 Gauss points): the
    # plant that made them is structurally the old model, so the fit reaches R^2 0.9948 where it
    # reached 0.9987; the coarse start's wrong valley gave 0.984.
    assert calibration.r_squared > 0.99
