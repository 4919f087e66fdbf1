"""A plant that runs the project's servo and feather FMUs, for the bench emulator.

The plant is a small scene (the `testbed` scene's physics: command -> servo -> feather, the
feather's root torque loading the servo) run by cosim's Simulator with strong coupling: the
servo and feather Model Exchange FMUs are one ODE integrated by CVODE to the tolerance, so the
emulated bench is the converged model, not a macro-step approximation of it. (Stepping the two
FMUs Gauss–Seidel at 1 ms, as this plant once did, is first-order in the step: for an asymmetric
stroke of the plain feather it served 13.3 mN of mean thrust where the converged model gives
2.65 mN; tests/hil/test_hil_fmu_plant.py.)

The setpoint the emulator receives is written into the scene's `command` source; the Simulator
restarts the solver at that jump. So a run against the emulator can be compared with the pure
simulation, and there is one master, not two.
"""
from __future__ import annotations

import math
from typing import Mapping

from ..cosim.coupling.simulator import Simulator
from ..cosim.errors import SceneError, StepError
from ..cosim.scene.data import Scene, scene_from_dict
from ..cosim.scene.graph import plan
from ..cosim.scene.plan import Plan
from .errors import HILError
from .plant import FmuPlantForm, PlantValue, feather_build_options

#: Plant time the emulated bench can run (its FMUs are told this stop time): a month.
HORIZON_S = 30 * 24 * 3600.0
#: The testbed scene's solver settings (non-stiff: Adams; the tolerance of every simulation).
METHOD, RTOL, ATOL = "adams", 1e-6, 1e-8
#: Thrust is sampled at least this often for its time integral `impulse_Ns` (trapezoid rule; a
#: setpoint jump falls on a sample, so the rule's error is O(h^2) of the smooth parts).
IMPULSE_SAMPLE_S = 5e-4


def plant_scene(morphology: str, feather_parameters: Mapping[str, float],
                servo_parameters: Mapping[str, float],
                feather_options: Mapping[str, PlantValue] | None = None) -> Scene:
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
        # Nothing is recorded (the emulator reads the ports), so the output grid is the horizon
        # itself. No energy guard: it judges recorded stroke periods, and this plant has neither
        # (a blow-up still stops the advance: CVODE fails, and the outputs are checked finite).
        # It starts at rest, as a bench left alone sits: servo at its setpoint, feather in its
        # buoyant equilibrium (from straight it would sag and ring, and the load cell would
        # tare somewhere in that ringing).
        "master": {"coupling": "strong", "method": METHOD, "rtol": RTOL, "atol": ATOL,
                   "t_end_s": HORIZON_S, "output_interval_s": HORIZON_S, "check_steps": False,
                   "passive_energy_factor": 0.0, "start_at_rest": True},
        "blocks": {
            "command": {"kind": "constant", "outputs": {"setpoint_rad": {"value": 0.0, "unit": "rad"}}},
            "servo": {"kind": "fmu", "model": "servo", "parameters": dict(servo_parameters)},
            "feather": {"kind": "fmu", "model": "feather", "options": {**dict(feather_options or {}), "morphology": morphology},
                        "parameters": dict(feather_parameters)},
            "tank": {"kind": "constant", "outputs": {"flow_speed_m_s": {"value": 0.0, "unit": "m/s"}}},
        },
    })


def plant_plan(morphology: str, form: FmuPlantForm) -> Plan:
    """The FMU plant's plan: every build option, name and value checked, no FMU built (CasADi
    only, well under a second), so a bad hidden setting is refused before the emulator compiles."""
    try:
        checked = plan(plant_scene(morphology, form.feather, form.servo, form.feather_options),
                       outputs=["servo.angle_rad", "feather.thrust_N"])
    except SceneError as exc:
        raise HILError(f"fmu plant: {exc}") from None
    # A scene may name parameters another model form lacks (the wake laws replace drag_coeff by
    # wake_drag_coeff); a hidden coefficient the plant would ignore must not pass as applied.
    for block, given in (("feather", form.feather), ("servo", form.servo)):
        model = checked.blocks[block].model
        known = [p.name for p in model.parameters]
        unknown = [name for name in given if name not in known]
        if unknown:
            options = ", ".join(f"{k}={v}" for k, v in model.options.items()) if block == "feather" else ""
            extra = f"; build options: {', '.join(feather_build_options())}" if block == "feather" else ""
            raise HILError(f"plant parameter(s) not applied: the {block} model"
                           f"{' (' + options + ')' if options else ''} has no coefficient "
                           f"{', '.join(repr(n) for n in unknown)}; its coefficients: {', '.join(known)}{extra}")
    return checked


class FmuPlant:
    """Servo + feather FMUs as one ODE, advanced to any time (the Plant protocol)."""

    def __init__(self, morphology: str = "chordwise", *,
                 feather_parameters: Mapping[str, float] | None = None,
                 servo_parameters: Mapping[str, float] | None = None,
                 feather_options: Mapping[str, PlantValue] | None = None) -> None:
        """`feather_options`: the feather's build options (its model form, e.g. {"wake": "plate"});
        `feather_parameters` / `servo_parameters`: coefficients that differ from the defaults."""
        self._plan = plant_plan(morphology, FmuPlantForm(dict(feather_options or {}), dict(feather_parameters or {}),
                                                         dict(servo_parameters or {})))
        self._sim: Simulator | None = None
        self._start()

    def _start(self) -> None:
        self._sim = Simulator(self._plan, record=False)
        # the plan's command block outlives a reset: back to the setpoint the plant rests at
        self._sim.write("command.setpoint_rad", 0.0)
        try:
            self._sim.initialize(0.0)
        except StepError as exc:
            self._sim.close()
            raise HILError(f"FmuPlant: {exc}") from None
        self._t_s = 0.0
        self._setpoint_rad = 0.0
        self._angle_rad = self._sim.read("servo.angle_rad")
        self._thrust_N = self._sim.read("feather.thrust_N")
        self._impulse_Ns = 0.0

    @property
    def t_s(self) -> float:
        """Plant time: the wall-clock time it has been advanced by since it started."""
        return self._t_s

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

    @property
    def impulse_Ns(self) -> float:
        """The time integral of thrust_N since the plant started (or was reset)."""
        return self._impulse_Ns

    def set_setpoint_rad(self, x: float) -> None:
        if x != self._setpoint_rad:
            self._setpoint_rad = x
            self._sim.write("command.setpoint_rad", x)
            # the servo's acceleration, and with it the thrust, jumps with the setpoint
            self._thrust_N = self._sim.read("feather.thrust_N")

    def advance(self, dt_s: float) -> None:
        """Integrate dt_s further (to the solver's tolerance, whatever dt_s)."""
        if not dt_s > 0:
            return
        sim = self._sim
        if self._t_s + dt_s > HORIZON_S:
            raise HILError(f"emulated plant ran past its horizon of {HORIZON_S:g} s: restart the emulator")
        n = math.ceil(dt_s / IMPULSE_SAMPLE_S)
        t0_s = self._t_s
        for k in range(1, n + 1):
            try:
                self._t_s = sim.advance_to(t0_s + dt_s * k / n)
            except StepError as exc:
                raise HILError(f"emulated plant failed: {exc}") from None
            thrust_N = sim.read("feather.thrust_N")
            self._impulse_Ns += 0.5 * (self._thrust_N + thrust_N) * dt_s / n
            self._thrust_N = thrust_N
        self._angle_rad = sim.read("servo.angle_rad")
        if not (math.isfinite(self._thrust_N) and math.isfinite(self._angle_rad)):
            raise HILError(f"emulated plant diverged at t={sim.t:.3f} s (thrust {self._thrust_N})")
