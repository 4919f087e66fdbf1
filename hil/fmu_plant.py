"""A plant that runs the project's servo and feather FMUs, for the bench emulator.

The two Co-Simulation FMUs are stepped Gauss–Seidel at a fixed macro step (servo first, then the
feather with the servo's fresh motion; the feather's root torque loads the servo on the next
step through the servo's filtered load input). This is the `testbed` scene's physics, so a run
against the emulator can be compared with the pure simulation.
"""
from __future__ import annotations

import math
from typing import Mapping

import fmpy
from fmpy import read_model_description
from fmpy.fmi3 import FMU3Slave

from fmu_src.catalog import build_model
from fmu_src.export import build_fmu

from .errors import HILError


class _Slave:
    """One CS instance with its variables' value references resolved once."""

    def __init__(self, model, parameters: Mapping[str, float], name: str) -> None:
        path = build_fmu(model)
        description = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in description.modelVariables}
        self.fmu = FMU3Slave(guid=description.guid, unzipDirectory=fmpy.extract(str(path)),
                             modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate()
        self.fmu.enterInitializationMode(tolerance=1e-6, startTime=0.0)
        values = model.parameter_vector(parameters)  # range-checked
        self.fmu.setFloat64([self.vr[p.name] for p in model.parameters], values)
        self.fmu.exitInitializationMode()

    def refs(self, *names: str) -> list[int]:
        return [self.vr[n] for n in names]


class FmuPlant:
    """Servo + feather FMUs advanced in macro steps of `step_s` (the Plant protocol)."""

    def __init__(self, morphology: str = "chordwise", *, step_s: float = 1e-3,
                 feather_parameters: Mapping[str, float] | None = None,
                 servo_parameters: Mapping[str, float] | None = None) -> None:
        if not (math.isfinite(step_s) and 0 < step_s <= 0.01):
            raise HILError(f"FmuPlant step_s = {step_s!r} s must be in (0, 0.01]")
        self.step_s = step_s
        self._build = (morphology, dict(feather_parameters or {}), dict(servo_parameters or {}))
        self._instantiate()

    def _instantiate(self) -> None:
        morphology, feather_parameters, servo_parameters = self._build
        self._servo = _Slave(build_model("servo"), servo_parameters, "emulated_servo")
        self._feather = _Slave(build_model("feather", {"morphology": morphology}), feather_parameters,
                               "emulated_feather")
        self._servo_in = self._servo.refs("setpoint_rad", "load_torque_Nm")
        self._servo_out = self._servo.refs("angle_rad", "rate_rad_s", "accel_rad_s2")
        self._feather_in = self._feather.refs("root_angle_rad", "root_rate_rad_s", "root_accel_rad_s2")
        self._feather_out = self._feather.refs("thrust_N", "root_torque_Nm")
        self._t_s = 0.0
        self._debt_s = 0.0
        self._setpoint_rad = 0.0
        self._angle_rad, self._thrust_N, self._torque_Nm = 0.0, 0.0, 0.0

    def reset(self) -> None:
        """Fresh FMU instances at rest: an FMU whose step failed is in an undefined state."""
        for slave in (self._servo, self._feather):
            try:
                slave.fmu.terminate()
                slave.fmu.freeInstance()
            except Exception:   # it already failed; a fresh instance replaces it either way
                pass
        self._instantiate()

    @property
    def angle_rad(self) -> float:
        return self._angle_rad

    @property
    def thrust_N(self) -> float:
        return self._thrust_N

    def set_setpoint_rad(self, x: float) -> None:
        self._setpoint_rad = x

    def advance(self, dt_s: float) -> None:
        """Advance by dt_s in whole macro steps; the remainder carries over to the next call."""
        self._debt_s += dt_s
        while self._debt_s >= self.step_s:
            self._servo.fmu.setFloat64(self._servo_in, [self._setpoint_rad, self._torque_Nm])
            self._servo.fmu.doStep(self._t_s, self.step_s)
            motion = self._servo.fmu.getFloat64(self._servo_out)
            self._feather.fmu.setFloat64(self._feather_in, motion)
            self._feather.fmu.doStep(self._t_s, self.step_s)
            self._thrust_N, self._torque_Nm = self._feather.fmu.getFloat64(self._feather_out)
            self._angle_rad = motion[0]
            self._t_s += self.step_s
            self._debt_s -= self.step_s
            if not (math.isfinite(self._thrust_N) and math.isfinite(self._angle_rad)):
                raise HILError(f"emulated plant diverged at t={self._t_s:.3f} s (thrust {self._thrust_N})")
