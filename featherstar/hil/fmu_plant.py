"""A plant that runs the project's servo and feather FMUs, for the bench emulator.

The plant is a small scene (the `testbed` scene's physics: command -> servo -> feather, the
feather's root torque loading the servo) stepped by cosim's Simulator with Gauss–Seidel
coupling at a fixed macro step: servo first, then the feather with the servo's fresh motion;
the root torque reaches the servo on the next step through its filtered load input. The setpoint
the emulator receives is written into the scene's `command` source. So a run against the
emulator can be compared with the pure simulation, and there is one master, not two.
"""
from __future__ import annotations

import math
from typing import Mapping

from ..cosim.errors import SceneError, StepError
from ..cosim.graph import plan
from ..cosim.scene import Scene, scene_from_dict
from ..cosim.simulator import Simulator

from .errors import HILError

#: Plant time the emulated bench can run (its FMUs are told this stop time): a month.
HORIZON_S = 30 * 24 * 3600.0


def plant_scene(morphology: str, step_s: float, feather_parameters: Mapping[str, float],
                servo_parameters: Mapping[str, float]) -> Scene:
    """The emulated bench as a scene: a `command` source for the servo setpoint, still water."""
    return scene_from_dict({
        "name": "emulated_testbed",
        "description": "the emulator's plant: commanded servo driving one feather in still water",
        "connections": [
            "command.setpoint_rad -> servo.setpoint_rad",
            "feather.root_torque_Nm -> servo.load_torque_Nm",
            "servo.angle_rad -> feather.root_angle_rad",
            "servo.rate_rad_s -> feather.root_rate_rad_s",
            "servo.accel_rad_s2 -> feather.root_accel_rad_s2",
            "tank.flow_speed_m_s -> feather.flow_speed_m_s",
        ],
        # No energy guard: it judges recorded stroke periods, and this plant has neither (a blow-up
        # still stops the step: every output is checked finite at every macro step).
        "master": {"coupling": "gauss-seidel", "step_s": step_s, "t_end_s": HORIZON_S, "rtol": 1e-6,
                   "passive_energy_factor": 0.0},
        "blocks": {
            "command": {"kind": "constant", "outputs": {"setpoint_rad": {"value": 0.0, "unit": "rad"}}},
            "servo": {"kind": "fmu", "model": "servo", "parameters": dict(servo_parameters)},
            "feather": {"kind": "fmu", "model": "feather", "options": {"morphology": morphology},
                        "parameters": dict(feather_parameters)},
            "tank": {"kind": "constant", "outputs": {"flow_speed_m_s": {"value": 0.0, "unit": "m/s"}}},
        },
    })


class FmuPlant:
    """Servo + feather FMUs advanced in macro steps of `step_s` (the Plant protocol)."""

    def __init__(self, morphology: str = "chordwise", *, step_s: float = 1e-3,
                 feather_parameters: Mapping[str, float] | None = None,
                 servo_parameters: Mapping[str, float] | None = None) -> None:
        if not (math.isfinite(step_s) and 0 < step_s <= 0.01):
            raise HILError(f"FmuPlant step_s = {step_s!r} s must be in (0, 0.01]")
        self.step_s = step_s
        try:
            self._plan = plan(plant_scene(morphology, step_s, dict(feather_parameters or {}),
                                          dict(servo_parameters or {})),
                              outputs=["servo.angle_rad", "feather.thrust_N"])
        except SceneError as exc:
            raise HILError(f"FmuPlant: {exc}") from None
        self._sim: Simulator | None = None
        self._start()

    def _start(self) -> None:
        self._sim = Simulator(self._plan, record=False)
        try:
            self._sim.initialize(0.0)
        except StepError as exc:
            self._sim.close()
            raise HILError(f"FmuPlant: {exc}") from None
        self._steps = 0          # macro steps taken: the plant's time is steps * step_s
        self._debt_s = 0.0
        self._setpoint_rad = 0.0
        self._angle_rad, self._thrust_N = 0.0, 0.0

    def close(self) -> None:
        if self._sim is not None:
            self._sim.close()
            self._sim = None

    def reset(self) -> None:
        """Fresh FMU instances at rest: an FMU whose step failed is in an undefined state."""
        self.close()
        self._start()

    @property
    def angle_rad(self) -> float:
        return self._angle_rad

    @property
    def thrust_N(self) -> float:
        return self._thrust_N

    def set_setpoint_rad(self, x: float) -> None:
        if x != self._setpoint_rad:
            self._setpoint_rad = x
            self._sim.write("command.setpoint_rad", x)

    def advance(self, dt_s: float) -> None:
        """Advance by dt_s in whole macro steps; the remainder carries over to the next call."""
        self._debt_s += dt_s
        n = int(self._debt_s / self.step_s + 1e-9)
        if n <= 0:
            return
        self._debt_s -= n * self.step_s
        self._steps += n
        sim = self._sim
        try:
            sim.advance_to(self._steps * self.step_s)
        except StepError as exc:
            raise HILError(f"emulated plant failed: {exc}") from None
        self._angle_rad = sim.read("servo.angle_rad")
        self._thrust_N = sim.read("feather.thrust_N")
        if not (math.isfinite(self._thrust_N) and math.isfinite(self._angle_rad)):
            raise HILError(f"emulated plant diverged at t={sim.t:.3f} s (thrust {self._thrust_N})")
