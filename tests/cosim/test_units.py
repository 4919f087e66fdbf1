"""Units on connections: FMI leaves a variable's unit optional, so a port that declares none
connects to anything (the plan notes it as unchecked); two declared units must name the same
unit unless the scene waives that one connection (`[units] waive`)."""
from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from featherstar.cosim.errors import SceneError
from featherstar.cosim.scene import graph
from featherstar.cosim.scene.data import scene_from_dict
from featherstar.cosim.swimmer.run import run_scene

UNITS = ["", " ", "1", "-", "m", "rad", "m/s", "N.m", "mm"]
CONN = "c.y -> g.u"


def _scene(unit_out: str, unit_in: str, waive: list[str] | None = None) -> dict:
    data = {
        "name": "units",
        "connections": [CONN],
        "master": {"coupling": "jacobi", "t_end_s": 0.01, "step_s": 0.005},
        "blocks": {
            "c": {"kind": "constant", "outputs": {"y": {"value": 2.0, "unit": unit_out}}},
            "g": {"kind": "gain", "gain": 3.0, "unit_in": unit_in, "unit_out": "1"},
            "rec": {"kind": "recorder", "signals": ["g.y"]},
        },
    }
    if waive is not None:
        data["units"] = {"waive": waive}
    return data


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(UNITS), st.sampled_from(UNITS), st.booleans())
def test_the_unit_rule_on_every_pair(unit_out, unit_in, waive):
    undeclared = not unit_out.strip() or not unit_in.strip()
    same = unit_out == unit_in or {unit_out, unit_in} <= {"1", "-"}
    scene = scene_from_dict(_scene(unit_out, unit_in, [CONN] if waive else None))
    if not undeclared and not same and not waive:
        with pytest.raises(SceneError) as err:
            graph.plan(scene)
        assert (f"unit mismatch on '{CONN}': output is in '{unit_out}', input expects '{unit_in}' "
                f"(if the values agree, waive it: [units] waive = [\"{CONN}\"])") in err.value.problems
        return
    notes = graph.plan(scene).notes
    unchecked = [n for n in notes if n.startswith("units not checked")]
    waived = [n for n in notes if n.startswith("unit check waived")]
    assert unchecked == ([f"units not checked (a port declares no unit): {CONN}"] if undeclared else [])
    assert waived == ([f"unit check waived by the scene ([units] waive): {CONN} ('{unit_out}' into "
                       f"'{unit_in}')"] if waive and not undeclared and not same else [])


def test_a_waiver_naming_no_connection_is_refused():
    scene = scene_from_dict(_scene("m", "m", ["c.y -> g.v"]))
    with pytest.raises(SceneError, match=r"\[units\] waive: 'c.y -> g.v' is not a connection of the scene"):
        graph.plan(scene)


@pytest.mark.parametrize("units", [["c.y -> g.u"], "c.y -> g.u", {"waive": "c.y"}, {"skip": []}])
def test_a_malformed_units_table_is_refused_by_name(units):
    data = _scene("m", "mm")
    data["units"] = units if isinstance(units, dict) else {"waive": units} if isinstance(units, str) else units
    with pytest.raises(SceneError, match=r"units"):
        scene_from_dict(data)


def test_a_waived_scene_runs_and_keeps_its_waiver_through_to_dict():
    scene = scene_from_dict(_scene("m", "rad", [CONN]))
    assert scene_from_dict(scene.to_dict()).unit_waivers == scene.unit_waivers
    assert run_scene(scene)["g.y"][-1] == 6.0
    assert "units" not in scene_from_dict(_scene("m", "m")).to_dict()   # fingerprints unchanged without


@pytest.mark.parametrize("version", [2, 3])
def test_a_third_party_fmu_without_units_connects_to_a_unit_carrying_port(c_fmu, version):
    """The events FMU declares no unit on `level`: the stroke's angle (rad) drives it directly."""
    scene = scene_from_dict({
        "name": "no-units", "connections": ["controller.angle_rad -> integ.level"],
        "master": {"coupling": "strong", "t_end_s": 0.2, "output_interval_s": 0.01},
        "blocks": {"controller": {"kind": "stroke"}, "integ": {"kind": "fmu", "fmu": str(c_fmu("events", version))},
                   "rec": {"kind": "recorder", "signals": ["integ.x"]}},
    })
    plan = graph.plan(scene)
    assert "units not checked (a port declares no unit): controller.angle_rad -> integ.level" in plan.notes
