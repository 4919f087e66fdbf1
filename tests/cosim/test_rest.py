"""Start at rest (master.start_at_rest): the state in which nothing moves, for the inputs at t0."""
from __future__ import annotations

import ctypes

import numpy as np
import pytest
from featherstar.cosim.coupling.rest import solve_rest
from featherstar.cosim.coupling.simulator import Simulator
from featherstar.cosim.errors import SceneError, StepError
from featherstar.cosim.scene.data import scene_from_dict
from featherstar.cosim.scene.graph import plan


def _bench(start_at_rest: bool, morphology: str = "plain") -> dict:
    """Servo at its setpoint 0 driving a plain feather in still water (the emulator's plant)."""
    scene = {
        "name": "rest", "description": "a plain feather left alone",
        "connections": ["feather.root_torque_Nm -> servo.load_torque_Nm",
                        "servo.angle_rad -> feather.root_angle_rad",
                        "servo.rate_rad_s -> feather.root_rate_rad_s",
                        "servo.accel_rad_s2 -> feather.root_accel_rad_s2",
                        "command.setpoint_rad -> servo.setpoint_rad",
                        "tank.flow_speed_m_s -> feather.flow_speed_m_s"],
        "master": {"coupling": "strong", "method": "adams", "t_end_s": 2.0, "output_interval_s": 0.01,
                   "start_at_rest": start_at_rest, "passive_energy_factor": 0.0},
        "blocks": {"command": {"kind": "constant", "outputs": {"setpoint_rad": {"value": 0.0, "unit": "rad"}}},
                   "tank": {"kind": "constant", "outputs": {"flow_speed_m_s": {"value": 0.0, "unit": "m/s"}}},
                   "servo": {"kind": "fmu", "model": "servo"},
                   "feather": {"kind": "fmu", "model": "feather", "options": {"morphology": morphology}}},
    }
    return scene


def _thrust(start_at_rest: bool, morphology: str = "plain") -> tuple[np.ndarray, dict]:
    with Simulator(plan(scene_from_dict(_bench(start_at_rest, morphology)), outputs=["feather.thrust_N"])) as sim:
        sim.initialize()
        sim.advance_to(2.0)
        return sim.recorded()[1]["feather.thrust_N"], dict(sim.context.stats)


@pytest.mark.parametrize("morphology", ["plain", "chordwise", "spanwise"])
def test_a_feather_started_at_rest_stays_at_rest_and_feels_no_force(morphology):
    """A body at rest in still water feels no dynamic force; from its start values (straight) the
    feather sags under its net buoyancy and the load cell reads the momentum it gains. The
    flapped feathers' hinges rest against their smoothed one-way stops (the solve's hard case)."""
    at_rest, stats = _thrust(True, morphology)
    straight, _ = _thrust(False, morphology)
    assert np.max(np.abs(at_rest)) < 1e-8
    assert np.max(np.abs(straight)) > 1e-3           # mN-size ringing, 5 orders above
    assert stats["start_at_rest"]["worst_rate_per_tolerance_1_s"] <= 1.0


def test_without_an_equilibrium_the_solve_fails_naming_the_state():
    """x' = 1 + x² never stops (a drive that keeps pushing); y' = -y comes to rest."""
    def rhs(t, y, yd):
        x, z = (ctypes.c_double * 2).from_address(y)
        out = (ctypes.c_double * 2).from_address(yd)
        out[0], out[1] = 1.0 + x * x, -z
        return 0
    with pytest.raises(StepError, match="cannot start at rest: state toy.x keeps changing") as info:
        solve_rest(rhs, 0.5, [0.2, 1.0], 1e-6, 1e-8, ["toy.x", "toy.z"])
    assert info.value.block == "toy" and info.value.t_s == 0.5


def test_start_at_rest_needs_the_strong_coupling():
    scene = _bench(True)
    scene["master"]["coupling"] = "gauss-seidel"
    with pytest.raises(SceneError, match="start_at_rest needs master.coupling = strong"):
        plan(scene_from_dict(scene))


def test_a_state_the_derivatives_ignore_keeps_its_start_value():
    """A damped body on a rail (x' = v, v' = -v): at rest for any position; the solve stops the
    body where it was and leaves the position alone instead of failing on the singular Jacobian."""
    def rhs(t, y, yd):
        x, v = (ctypes.c_double * 2).from_address(y)
        out = (ctypes.c_double * 2).from_address(yd)
        out[0], out[1] = v, -v
        return 0
    rest = solve_rest(rhs, 0.0, [3.0, 2.0], 1e-6, 1e-8, ["body.x", "body.v"])
    assert rest.y[0] == pytest.approx(3.0, abs=1e-12)
    assert abs(rest.y[1]) <= 1e-8 and rest.worst_rate_per_tolerance <= 1.0
