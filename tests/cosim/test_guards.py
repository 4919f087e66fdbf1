"""The master's guards: steps too coarse are refused before the run, created energy stops it."""
from __future__ import annotations

import dataclasses
import math

import pytest
from featherstar.cosim.errors import SceneError, StepError
from featherstar.cosim.framework.block import Passivity, Port, passivity_by_convention
from featherstar.cosim.scene import graph
from featherstar.cosim.scene.guards import PassiveEnergyGuard, feedback_loops, passive_energy_guards, step_problems
from featherstar.cosim.scenes import load_scene


def _problems(scene: str, overrides: dict) -> list[str]:
    """What the step check says of a scene (planned with the check lifted, so the plan exists)."""
    lifted = load_scene(scene).with_overrides({**overrides, "master.check_steps": False})
    plan = graph.plan(lifted)
    return step_problems(dataclasses.replace(plan, scene=lifted.with_overrides({"master.check_steps": True})))


def test_shipped_defaults_pass_the_step_check():
    for scene in ("testbed", "robot", "kinematic"):
        for coupling in ("strong", "jacobi", "gauss-seidel"):
            assert _problems(scene, {"master.coupling": coupling}) == []


def test_feedback_loops_are_found_through_any_port():
    assert feedback_loops(graph.plan(load_scene("testbed"))) == [["feather", "servo"]]
    # the right feather is deduplicated into the left one
    assert feedback_loops(graph.plan(load_scene("robot"))) == [["feather_left", "robot", "servo"]]
    assert feedback_loops(graph.plan(load_scene("kinematic"))) == []


def test_loop_limit_follows_the_fastest_time_constant_and_the_coupling():
    jacobi_6ms = _problems("testbed", {"master.coupling": "jacobi", "master.step_s": 6e-3})
    assert len(jacobi_6ms) == 1 and "servo.load_filter_time_constant_s = 0.005 s" in jacobi_6ms[0]
    assert "feather <-> servo" in jacobi_6ms[0]
    assert _problems("testbed", {"master.coupling": "gauss-seidel", "master.step_s": 6e-3}) == []
    assert _problems("testbed", {"master.coupling": "gauss-seidel", "master.step_s": 1.1e-2})
    # a slower load filter: the rate loop's 10 ms is now the fastest time constant
    slow_filter = {"servo.load_filter_time_constant_s": 0.02, "master.coupling": "jacobi"}
    assert _problems("testbed", {**slow_filter, "master.step_s": 1e-2}) == []
    assert any("servo.rate_time_constant_s" in p
               for p in _problems("testbed", {**slow_filter, "master.step_s": 1.2e-2}))
    # no loop, no loop limit: the kinematic scene only has the ramp limit (0.25 s / 25 = 10 ms)
    assert _problems("kinematic", {"master.coupling": "jacobi", "master.step_s": 1e-2}) == []


def test_ramp_limit_follows_the_shortest_ramp():
    faster_up = {"controller.t_up_s": 0.1, "controller.t_hold_up_s": 0.65}
    assert _problems("kinematic", {**faster_up, "master.output_interval_s": 4e-3}) == []
    (problem,) = _problems("kinematic", {**faster_up, "master.output_interval_s": 5e-3})
    assert "controller.t_up_s = 0.1 s" in problem and "at most 0.004 s" in problem
    # weak couplings record at every macro step: the step is the grid, the output interval unused
    assert _problems("kinematic", {"master.coupling": "jacobi", "master.output_interval_s": 0.5}) == []
    assert "master.step_s" in _problems("kinematic", {**faster_up, "master.coupling": "jacobi",
                                                      "master.step_s": 5e-3})[0]


def test_adaptive_macro_steps_and_the_lifted_check_are_not_judged():
    assert _problems("testbed", {"master.coupling": "jacobi", "master.step_s": 0.05, "master.adaptive": True}) == []
    plan = graph.plan(load_scene("testbed").with_overrides(
        {"master.coupling": "jacobi", "master.step_s": 0.05, "master.check_steps": False}))
    assert step_problems(plan) == []


def test_refusal_is_a_scene_error_listing_every_problem():
    with pytest.raises(SceneError) as info:
        graph.plan(load_scene("testbed").with_overrides({"master.coupling": "jacobi", "master.step_s": 0.05}))
    text = str(info.value)
    assert "2 problems" in text and "shortest ramp" in text and "feedback loop" in text
    assert "master.check_steps = false" in text


class _Unit:
    """Just enough of a Unit for a guard: a rigid plate of inertia I driven at its root."""

    name = "plate"
    output_names = ["root_torque_Nm", "mechanical_energy_J"]
    input_names = ["root_rate_rad_s"]

    def __init__(self) -> None:
        self.outbuf = [0.0, 0.0]
        self.inbuf = [0.0]

    def at(self, rate: float, accel: float, inertia: float, extra_J: float = 0.0) -> None:
        self.outbuf[:] = [inertia * accel, 0.5 * inertia * rate * rate + extra_J]
        self.inbuf[0] = rate


def _drive(guard: PassiveEnergyGuard, unit: _Unit, t_end: float, extra=lambda t: 0.0) -> None:
    """Spin up and down with rate sin(2 pi t): E = W exactly for the rigid plate."""
    for k in range(int(t_end / 1e-3) + 1):
        t = k * 1e-3
        unit.at(math.sin(2 * math.pi * t), 2 * math.pi * math.cos(2 * math.pi * t), 0.01, extra(t))
        guard(t)


def _passivity(unit: _Unit):
    return passivity_by_convention({n: Port(n, "") for n in unit.input_names},
                                   {n: Port(n, "") for n in unit.output_names})


def _guards(unit: _Unit, factor: float = 2.0):
    return passive_energy_guards({"plate": unit}, {"plate": _passivity(unit)}, factor=factor, judge_from_s=0.5)


def test_the_port_convention_declares_the_power_ports():
    assert _passivity(_Unit()) == Passivity("mechanical_energy_J", (("root_torque_Nm", "root_rate_rad_s"),))
    assert passivity_by_convention({"u": Port("u", "")}, {"mechanical_energy_J": Port("e", "J")}) is None


def test_the_shipped_feather_declares_itself_passive_and_the_servo_does_not():
    blocks = graph.plan(load_scene("testbed")).blocks
    assert blocks["feather"].passivity is not None and blocks["servo"].passivity is None


def test_energy_guard_finds_the_power_ports_and_passes_a_conservative_block():
    unit = _Unit()
    (guard,) = _guards(unit)
    assert guard.pairs == [(0, 0)] and guard.energy_index == 1
    _drive(guard, unit, 3.0)
    assert guard.work_in_J == pytest.approx(6 * 0.5 * 0.01 * 1.0**2, rel=1e-3)  # six spin-ups to 1 rad/s
    assert _guards(unit, factor=0.0) == []
    assert passive_energy_guards({"plate": unit}, {"plate": None}, factor=2.0, judge_from_s=0.5) == []


def test_energy_guard_stops_created_energy_naming_block_time_and_cause():
    unit = _Unit()
    guard = _guards(unit)[0]
    # 0.05 J appear from nowhere at t = 1.2 s, over three times the 0.0145 J the ports put in by then
    with pytest.raises(StepError) as info:
        _drive(guard, unit, 3.0, extra=lambda t: 0.05 if t >= 1.2 else 0.0)
    assert info.value.block == "plate" and info.value.t_s == pytest.approx(1.2)
    assert "root_torque_Nm x root_rate_rad_s" in str(info.value) and "likely cause" in str(info.value)


def test_energy_guard_waits_for_the_judging_time():
    unit = _Unit()
    guard = _guards(unit)[0]
    # 0.02 J appear at 0.1 s, four times the work by 0.5 s: stopped at the first judged sample
    with pytest.raises(StepError) as info:
        _drive(guard, unit, 1.0, extra=lambda t: 0.02 if t >= 0.1 else 0.0)
    assert info.value.t_s == pytest.approx(0.5)


@pytest.mark.parametrize("override,message", [
    ({"master.passive_energy_factor": -1}, "must be a finite number >= 0"),
    ({"master.passive_energy_factor": "nan"}, "must be a finite number >= 0"),
    ({"master.passive_energy_factor": "lots"}, "is not a valid float"),
    ({"master.check_steps": "maybe"}, "is not a valid bool"),
    ({"master.check_steps": 3}, "is not a valid bool"),
])
def test_guard_options_refuse_garbage(override, message):
    (key,) = override
    with pytest.raises(SceneError, match=rf"{key} = .*{message}"):
        graph.plan(load_scene("testbed").with_overrides(override))
