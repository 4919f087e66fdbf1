"""Scenes as data: loading, overrides, and the wiring checks (before any FMU is loaded)."""
from __future__ import annotations

import dataclasses
import math

import pytest
from conftest import OSCILLATOR, make_scene
from featherstar.cosim.errors import SceneError
from featherstar.cosim.scene import graph
from featherstar.cosim.scene.blocks import resolve
from featherstar.cosim.scene.data import scene_from_dict
from featherstar.cosim.scenes import list_scenes, load_scene


def test_shipped_scenes_listed_with_descriptions():
    names = dict(list_scenes())
    assert {"testbed", "robot", "kinematic"} <= set(names)
    assert all(desc and "\n" not in desc for desc in names.values())


@pytest.mark.parametrize("name", ["testbed", "robot", "kinematic"])
def test_shipped_scenes_validate(name):
    plan = graph.plan(load_scene(name))
    assert plan.t_end_s > 0 and plan.period_s == pytest.approx(1.5)
    assert not plan.loops  # the servo's load torque is filtered: no algebraic loop


def test_scene_is_frozen_and_overrides_return_new_scene():
    scene = load_scene("testbed")
    other = scene.with_overrides({"feather.morphology": "spanwise", "master.coupling": "jacobi",
                                  "master.step_s": "5e-4", "controller.t_up_s": 0.2})
    assert scene.master.coupling == "strong" and other.master.coupling == "jacobi"
    assert other.master.step_s == 5e-4
    assert scene.fingerprint() != other.fingerprint()
    with pytest.raises(dataclasses.FrozenInstanceError):
        scene.master.coupling = "jacobi"  # type: ignore[misc]
    rb = resolve(other.block("feather"))
    assert rb.model.name.endswith("spanwise")
    assert "length_ratio" in rb.parameters and "width_ratio" not in rb.parameters


def test_required_set_names_work():
    scene = load_scene("testbed").with_overrides({
        "feather.morphology": "chordwise", "feather.width_ratio": "5.5",
        "controller.t_up_s": "0.3", "controller.t_down_s": "0.2", "controller.t_hold_up_s": "0.4",
        "controller.t_hold_down_s": "0.6", "controller.amplitude_deg": "50",
        "master.coupling": "gauss-seidel", "master.step_s": "0.002"})
    stroke = resolve(scene.block("controller")).obj.stroke
    assert (stroke.t_up_s, stroke.t_down_s, stroke.t_hold_up_s, stroke.t_hold_down_s) == (0.3, 0.2, 0.4, 0.6)
    assert stroke.amplitude_deg == 50
    assert resolve(scene.block("feather")).parameters["width_ratio"] == 5.5
    spanwise = load_scene("testbed").with_overrides({"feather.morphology": "spanwise", "feather.length_ratio": 2.5})
    assert resolve(spanwise.block("feather")).parameters["length_ratio"] == 2.5
    robot = load_scene("robot").with_overrides({"feather.morphology": "plain"})  # alias: both feathers
    assert {resolve(robot.block(n)).model.name for n in ("feather_left", "feather_right")} == {"feather_plain"}


def test_period_override_keeps_log_ratios():
    base = load_scene("testbed").with_overrides({"controller.t_up_s": 0.1, "controller.t_down_s": 0.4})
    before = resolve(base.block("controller")).obj.stroke
    after = resolve(base.with_overrides({"controller.period_s": 3.0}).block("controller")).obj.stroke
    assert after.period_s == pytest.approx(3.0)
    assert after.log_ratios() == pytest.approx(before.log_ratios())
    ratios = resolve(load_scene("testbed").with_overrides(
        {"controller.period_s": 1.5, "controller.log10_up_down": -0.5}).block("controller")).obj.stroke
    assert math.log10(ratios.t_up_s / ratios.t_down_s) == pytest.approx(-0.5)
    assert ratios.period_s == pytest.approx(1.5)
    with pytest.raises(SceneError, match="period_s"):
        resolve(load_scene("testbed").with_overrides({"controller.period_s": 2.0, "controller.t_up_s": 0.1})
                .block("controller"))


def test_bad_override_names():
    with pytest.raises(SceneError) as err:
        load_scene("testbed").with_overrides({"feather.bogus": 1, "nosuch.x": 1, "master.nope": 2,
                                              "master.coupling": "sideways"})
    text = str(err.value)
    assert "no block named 'nosuch'" in text and "master has no setting 'nope'" in text
    with pytest.raises(SceneError, match="bogus"):
        graph.plan(load_scene("testbed").with_overrides({"feather.bogus": 1}))
    with pytest.raises(SceneError, match="coupling"):
        graph.plan(load_scene("testbed").with_overrides({"master.coupling": "sideways"}))
    with pytest.raises(SceneError, match="width_ratio"):  # a plain feather has no width ratio
        graph.plan(load_scene("testbed").with_overrides({"feather.morphology": "plain", "feather.width_ratio": 5}))


def test_unknown_block_model_and_port():
    data = dict(OSCILLATOR, connections=["a.position_m -> b.other_position_m", "a.velocity -> b.other_velocity_m_s",
                                         "b.force_N -> a.force_N", "c.y -> a.force_N"])
    data["blocks"] = dict(OSCILLATOR["blocks"], d={"kind": "fmu", "model": "no_such_model"},
                          e={"kind": "teleporter"})
    with pytest.raises(SceneError) as err:
        graph.plan(scene_from_dict(data))
    problems = err.value.problems
    assert any("unknown model kind 'no_such_model'" in p for p in problems)
    assert any("unknown block kind 'teleporter'" in p for p in problems)
    assert any("block 'a' has no output 'velocity'" in p and "its outputs: position_m, velocity_m_s" in p
               for p in problems)
    assert any("unknown block 'c'" in p for p in problems)


def test_dangling_and_doubly_driven_inputs():
    scene = make_scene(OSCILLATOR, connections=["a.position_m -> b.other_position_m",
                                                "a.velocity_m_s -> b.other_position_m",
                                                "b.force_N -> a.force_N"])
    with pytest.raises(SceneError) as err:
        graph.plan(scene)
    text = str(err.value)
    assert "input b.other_position_m is driven twice: by a.position_m and by a.velocity_m_s" in text
    assert "input b.other_velocity_m_s is not connected (dangling)" in text


def test_unit_mismatch_and_output_used_as_input():
    scene = make_scene(OSCILLATOR, connections=["a.velocity_m_s -> b.other_position_m",
                                                "a.position_m -> b.other_velocity_m_s",
                                                "b.force_N -> a.force_N", "a.position_m -> b.force_N"])
    with pytest.raises(SceneError) as err:
        graph.plan(scene)
    text = str(err.value)
    assert "unit mismatch on 'a.velocity_m_s -> b.other_position_m': output is in 'm/s', input expects 'm'" in text
    assert "block 'b' has no input 'force_N' (that is an output)" in text


LOOP = {
    "name": "loop",
    "connections": ["g1.y -> g2.u", "g2.y -> g1.u"],
    "master": {"t_end_s": 0.1, "output_interval_s": 0.01},
    "blocks": {
        "g1": {"kind": "gain", "gain": 0.5, "offset": 1.0},
        "g2": {"kind": "gain", "gain": -2.0, "offset": 3.0},
        "rec": {"kind": "recorder", "signals": ["g1.y", "g2.y"]},
    },
}


def test_loop_found_and_described_port_by_port():
    plan = graph.plan(make_scene(LOOP))
    assert len(plan.loops) == 1
    assert plan.loops[0].describe() == "g1.y -> g2.u -> g2.y -> g1.u -> g1.y"


def test_unsolvable_loop_is_named_port_by_port():
    data = make_scene(LOOP, blocks={"g2": {"kind": "gain", "gain": -2.0, "offset": 3.0, "can_iterate": False}})
    with pytest.raises(SceneError) as err:
        graph.plan(data)
    assert "algebraic loop g1.y -> g2.u -> g2.y -> g1.u -> g1.y cannot be solved" in str(err.value)
    assert "g2" in str(err.value)
    with pytest.raises(SceneError, match="algebraic loop g1.y -> g2.u"):
        graph.plan(make_scene(LOOP, master={"algebraic_loops": "error"}))


def test_strong_coupling_refuses_stateful_python_block():
    data = make_scene(LOOP, blocks={"g1": {"kind": "python", "factory": "toy_blocks:Integrator"}},
                      connections=["g1.y -> g2.u", "g2.y -> g1.u"])
    with pytest.raises(SceneError, match="jacobi or gauss-seidel"):
        graph.plan(data)


def test_pruning_and_dedup_in_plan():
    plan = graph.plan(load_scene("robot"))
    assert plan.alias_of["feather_right"] == "feather_left"
    assert "feather_right" not in plan.instantiate
    data = make_scene(OSCILLATOR, blocks={"extra": {"kind": "fmu", "model": "toys:oscillator_a",
                                                    "parameters": {"mass_kg": 2.0}},
                                          "rec": {"kind": "recorder", "signals": ["b.position_m"]}},
                      connections=OSCILLATOR["connections"] + ["b.force_N -> extra.force_N"])
    plan = graph.plan(data)
    assert plan.pruned == ["extra"] and "extra" not in plan.instantiate
    plan = graph.plan(data, outputs=["extra.position_m"])
    assert "extra" in plan.instantiate
    same = make_scene(OSCILLATOR, blocks={"extra": {"kind": "fmu", "model": "toys:oscillator_a"}},
                      connections=OSCILLATOR["connections"] + ["b.force_N -> extra.force_N"])
    plan = graph.plan(same, outputs=["extra.position_m"])  # same model, same drive: computed by 'a'
    assert plan.alias_of["extra"] == "a" and "extra" not in plan.instantiate


def test_feather_drag_amplitude_follows_the_stroke_unless_set():
    """The oscillatory drag's KC comes from the stroke amplitude, which lives in the controller."""
    base = load_scene("testbed")
    assert graph.plan(base).blocks["feather"].parameters["stroke_amplitude_rad"] == pytest.approx(math.radians(60))
    wide = graph.plan(base.with_overrides({"controller.amplitude_deg": 90}))
    assert wide.blocks["feather"].parameters["stroke_amplitude_rad"] == pytest.approx(math.radians(90))
    assert any("stroke_amplitude_rad" in note for note in wide.notes)
    pinned = graph.plan(base.with_overrides({"controller.amplitude_deg": 90, "feather.stroke_amplitude_rad": 0.5}))
    assert pinned.blocks["feather"].parameters["stroke_amplitude_rad"] == 0.5
    robot = graph.plan(load_scene("robot"))  # both feathers follow, and stay identical (integrated once)
    assert robot.alias_of["feather_right"] == "feather_left"
    with pytest.raises(SceneError, match="stroke_amplitude_rad"):
        graph.plan(base.with_overrides({"feather.stroke_amplitude_rad": -1}))
