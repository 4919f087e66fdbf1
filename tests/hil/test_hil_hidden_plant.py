"""The emulator's plant with coefficients that differ from the defaults, hidden from the client."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from featherstar.hil.emulator import spawn_emulator
from featherstar.hil.errors import HILError
from featherstar.hil.plant import FlatPlatePlant, flat_plate_plant, fmu_plant_parameters, read_plant_parameters

pytestmark = pytest.mark.hil


def _thrust_swing_N(plant: FlatPlatePlant) -> float:
    """Peak-to-peak thrust of a 0.5 rad step response."""
    plant.set_setpoint_rad(0.5)
    thrust = []
    for _ in range(400):
        plant.advance(1e-3)
        thrust.append(plant.thrust_N)
    return float(np.ptp(thrust))


def test_changed_coefficients_change_the_plant_and_the_defaults_stay():
    default = _thrust_swing_N(FlatPlatePlant())
    assert _thrust_swing_N(flat_plate_plant({})) == default
    # Thrust is linear in both fluid coefficients: doubling both doubles it exactly.
    assert _thrust_swing_N(flat_plate_plant({"c_n": 2.4, "c_a": 1.4})) == pytest.approx(2 * default, rel=1e-9)


def test_parameters_from_a_file_and_the_command_line(tmp_path):
    path = tmp_path / "hidden.json"
    path.write_text(json.dumps({"feather.drag_coeff": 1.6, "servo.tau_s": 0.02}))
    merged = read_plant_parameters(path, ["feather.drag_coeff=1.8", "added_mass_scale=1.2"])
    assert merged == {"feather.drag_coeff": 1.8, "servo.tau_s": 0.02, "added_mass_scale": 1.2}
    assert fmu_plant_parameters(merged) == ({"drag_coeff": 1.8, "added_mass_scale": 1.2}, {"tau_s": 0.02})


@pytest.mark.parametrize("make, message", [
    (lambda: flat_plate_plant({"drag": 1.0}), "has no parameter(s) 'drag'"),
    (lambda: flat_plate_plant({"c_n": -1.0}), "'c_n' = -1.0 must be >= 0"),
    (lambda: read_plant_parameters(None, ["c_n=fast"]), "must be a finite number"),
    (lambda: read_plant_parameters(None, ["c_n"]), "must read NAME=VALUE"),
    (lambda: fmu_plant_parameters({"robot.mass_kg": 1.0}), "blocks 'feather' and 'servo'"),
])
def test_bad_plant_parameters_are_refused(make, message):
    with pytest.raises(HILError, match=message.replace("(", r"\(").replace(")", r"\)")):
        make()


def test_hidden_coefficients_are_not_printed_nor_on_the_command_line():
    emulator = spawn_emulator(plant="flat-plate", plant_parameters={"c_n": 2.345678})
    try:
        listing = open(f"/proc/{emulator.proc.pid}/cmdline").read().replace("\0", " ")
        assert "--plant-parameters" in listing and "2.345678" not in listing
    finally:
        emulator.stop()


def test_an_out_of_range_feather_coefficient_stops_the_emulator_in_one_line():
    done = subprocess.run([sys.executable, "-m", "featherstar.hil", "emulate", "--port", "0", "--plant", "fmu",
                           "--morphology", "plain", "--plant-set", "feather.added_mass_scale=7"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode != 0
    assert "added_mass_scale" in done.stderr and "outside its valid range" in done.stderr
