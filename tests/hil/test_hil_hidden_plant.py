"""The emulator's plant with coefficients that differ from the defaults, hidden from the client."""
from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest

from featherstar.hil.emulator import spawn_emulator
from featherstar.hil.errors import HILError
from featherstar.hil.fmu_plant import plant_plan
from featherstar.hil.plant import (FlatPlatePlant, FmuPlantForm, feather_build_options, flat_plate_plant, fmu_plant_form,
                                  read_plant_parameters)
from hypothesis import given, settings, strategies as st

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
    path.write_text(json.dumps({"feather.drag_coeff": 1.6, "servo.tau_s": 0.02, "feather.wake": "self",
                                "feather.drag_split": True}))
    merged = read_plant_parameters(path, ["feather.drag_coeff=1.8", "added_mass_scale=1.2", "feather.wake=plate",
                                          "drag_points=8"])
    assert merged == {"feather.drag_coeff": 1.8, "servo.tau_s": 0.02, "added_mass_scale": 1.2,
                      "feather.wake": "plate", "feather.drag_split": True, "drag_points": 8}
    assert fmu_plant_form(merged) == FmuPlantForm({"wake": "plate", "drag_split": True, "drag_points": 8},
                                                  {"drag_coeff": 1.8, "added_mass_scale": 1.2}, {"tau_s": 0.02})


@pytest.mark.parametrize("make, message", [
    (lambda: flat_plate_plant({"drag": 1.0}), "has no parameter(s) 'drag'"),
    (lambda: flat_plate_plant({"c_n": -1.0}), "'c_n' = -1.0 must be >= 0"),
    (lambda: read_plant_parameters(None, ["c_n=fast"]), "must be a finite number"),
    (lambda: read_plant_parameters(None, ["c_n"]), "must read NAME=VALUE"),
    (lambda: fmu_plant_form({"robot.mass_kg": 1.0}), "blocks 'feather' and 'servo'"),
    (lambda: read_plant_parameters(None, ["feather.morphology=plain"]), "chosen with --morphology"),
    (lambda: read_plant_parameters(None, ["servo.wake=plate"]), "must be a finite number"),
    (lambda: flat_plate_plant(read_plant_parameters(None, ["feather.wake=plate"])), "has no parameter(s) 'feather.wake'"),
])
def test_bad_plant_parameters_are_refused(make, message):
    with pytest.raises(HILError, match=message.replace("(", r"\(").replace(")", r"\)")):
        make()


# Every wrong model form is refused by the plan (CasADi, no FMU built) in one line that lists the
# valid values, or names the valid range.
BAD_FORMS = [
    ({"wake": "plat"}, "valid: none, relative, self, plate"),
    ({"wake": 3}, "valid: none, relative, self, plate"),
    ({"drag_points": 0}, "drag_points = 0 must be an integer in [1, 64]"),
    ({"drag_points": "many"}, "must be an integer in [1, 64]"),
    ({"drag_split": "maybe"}, "drag_split = 'maybe' must be true or false"),
    ({"n_units": 1}, "n_units = 1 must be an integer in [2, 60]"),
    ({"root_support": True}, "root_support applies to the spanwise morphology only"),
]


@pytest.mark.parametrize("options, message", BAD_FORMS)
def test_a_bad_model_form_is_refused_in_one_line_before_any_fmu_build(options, message):
    plant_plan("plain", FmuPlantForm({}, {}, {}))   # warm: the import and the first model build
    started = time.perf_counter()
    with pytest.raises(HILError) as caught:
        plant_plan("plain", FmuPlantForm(options, {}, {}))
    assert time.perf_counter() - started < 1.0
    assert message in str(caught.value) and "\n" not in str(caught.value)


def test_a_coefficient_the_model_form_lacks_is_refused_with_the_forms_coefficients():
    # a wake law replaces the quasi-steady drag_coeff by its own C_0 (wake_drag_coeff)
    started = time.perf_counter()
    with pytest.raises(HILError, match="not applied: the feather model .*wake=plate.* no coefficient 'drag_coeff'; its coefficients: .*wake_drag_coeff"):
        plant_plan("plain", fmu_plant_form({"feather.wake": "plate", "feather.drag_coeff": 1.2}))
    assert time.perf_counter() - started < 1.0
    with pytest.raises(HILError, match="not applied: the servo model has no coefficient 'tau'; its coefficients: no_load"):
        plant_plan("plain", fmu_plant_form({"servo.tau": 0.1}))
    good = plant_plan("plain", fmu_plant_form({"feather.wake": "plate", "feather.wake_drag_coeff": 1.4}))
    assert good.blocks["feather"].model.options["wake"] == "plate"


@settings(max_examples=25, deadline=None)
@given(st.text(alphabet="abcdefghijklmnopqrstuvwxyz_", min_size=1, max_size=12))
def test_any_unknown_wake_law_is_refused_listing_the_laws(law):
    if law in ("none", "relative", "self", "plate"):
        return
    with pytest.raises(HILError, match="valid: none, relative, self, plate"):
        plant_plan("plain", fmu_plant_form(read_plant_parameters(None, [f"feather.wake={law}"])))


def test_every_build_option_but_the_morphology_is_a_plant_setting():
    assert set(feather_build_options()) == {"n_units", "root_support", "drag_points", "drag_split", "wake"}


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


def test_the_emulator_command_refuses_a_bad_wake_law_in_one_line():
    done = subprocess.run([sys.executable, "-m", "featherstar.hil", "emulate", "--port", "0", "--plant", "fmu",
                           "--morphology", "plain", "--plant-set", "feather.wake=plates"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2
    assert done.stderr.strip().count("\n") == 0 and "valid: none, relative, self, plate" in done.stderr


def test_the_emulator_serves_a_plant_of_another_model_form_keeping_it_hidden():
    emulator = spawn_emulator(plant="fmu", morphology="plain", start_timeout_s=300,
                              plant_parameters={"feather.wake": "plate", "feather.wake_drag_coeff": 1.234567})
    try:
        listing = open(f"/proc/{emulator.proc.pid}/cmdline").read().replace("\0", " ")
        assert "plate" not in listing and "1.234567" not in listing
    finally:
        emulator.stop()
