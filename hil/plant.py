"""Plants the emulator puts behind the register maps: servo + feather, advanced in real time.

`Plant` is the protocol; `FlatPlatePlant` is the analytic default. A plant running the project's
feather FMUs only needs the same four members. A plant that also keeps `impulse_Ns`, the time
integral of its thrust since it started (or was reset), gets an integrating load cell: each
reading is the mean force since the previous one, as a sigma-delta load-cell converter reports
(featherstar.hil.converter); without it a reading is the instantaneous thrust.

Convention: angle 0 = feather horizontal; positive angle = tip up; thrust positive up (the
tared load-cell reading of the simulated feather).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Mapping, Protocol, Sequence, runtime_checkable

from ..cosim.scene.specs import parse_value
from ..fmu_src.catalog import build_options
from .errors import HILError


@runtime_checkable
class Plant(Protocol):
    @property
    def angle_rad(self) -> float: ...

    @property
    def thrust_N(self) -> float: ...

    def set_setpoint_rad(self, x: float) -> None: ...

    def advance(self, dt_s: float) -> None: ...


@dataclass
class FlatPlatePlant:
    """A rate-limited servo driving a rigid flat plate that rotates about its root in water.

    Servo: a first-order position loop, rate command clip((setpoint - angle) / tau_s, +-rate
    limit), followed by a motor lag tau_motor_s so that the acceleration (and with it the
    added-mass force) stays finite. With tau_motor_s = tau_s / 4 the loop is critically damped.

    Fluid: strip theory along the span r in [0, l] of a plate of width w whose normal velocity
    is r*omega and normal acceleration r*alpha. Per unit span, the normal force on the plate is
        -(m_a' r alpha + 1/2 rho C_n w |r omega| r omega),  m_a' = C_a rho pi w^2 / 4
    (the added mass of a 2D flat plate, scaled by C_a). Integrated over the span:
        F_n = -(C_a rho pi w^2 l^2 / 8 * alpha + rho C_n w l^3 / 6 * omega |omega|).
    The plate's normal is vertical at angle 0, so the root force on the thrust (vertical) axis is
        thrust_N = F_n cos(angle).
    A downstroke (omega < 0) pushes water down and gives positive thrust. Plate inertia and
    weight are left out: a 0.4 mm polypropylene feather weighs about 3 g, nearly buoyant.
    """

    length_m: float = 0.12
    width_m: float = 0.075
    rho_kg_m3: float = 1000.0
    c_n: float = 1.2
    c_a: float = 0.7
    tau_s: float = 0.05
    tau_motor_s: float = 0.0125
    rate_limit_rad_s: float = 6.2
    limit_rad: float = math.pi / 2
    max_dt_s: float = 5e-4
    angle_rad: float = 0.0
    rate_rad_s: float = 0.0
    accel_rad_s2: float = 0.0
    setpoint_rad: float = field(default=0.0, init=False)
    impulse_Ns: float = field(default=0.0, init=False)

    @property
    def added_mass_kg_m(self) -> float:
        """Root force per unit angular acceleration, N / (rad/s^2)."""
        return self.c_a * self.rho_kg_m3 * math.pi * self.width_m**2 * self.length_m**2 / 8

    @property
    def drag_kg_m(self) -> float:
        """Root force per unit omega|omega|, N / (rad/s)^2."""
        return self.rho_kg_m3 * self.c_n * self.width_m * self.length_m**3 / 6

    @property
    def thrust_N(self) -> float:
        normal_N = -(self.added_mass_kg_m * self.accel_rad_s2
                     + self.drag_kg_m * self.rate_rad_s * abs(self.rate_rad_s))
        return normal_N * math.cos(self.angle_rad)

    def set_setpoint_rad(self, x: float) -> None:
        self.setpoint_rad = min(max(x, -self.limit_rad), self.limit_rad)

    def reset(self) -> None:
        """Back to rest at angle 0 (the emulator's recovery from a failed step)."""
        self.angle_rad = self.rate_rad_s = self.accel_rad_s2 = self.setpoint_rad = self.impulse_Ns = 0.0

    def advance(self, dt_s: float) -> None:
        """Semi-implicit Euler in substeps of at most max_dt_s (tau_motor_s / 25 by default)."""
        if dt_s <= 0:
            return
        n = math.ceil(dt_s / self.max_dt_s)
        h = dt_s / n
        for _ in range(n):
            command = (self.setpoint_rad - self.angle_rad) / self.tau_s
            command = min(max(command, -self.rate_limit_rad_s), self.rate_limit_rad_s)
            self.accel_rad_s2 = (command - self.rate_rad_s) / self.tau_motor_s
            self.rate_rad_s += self.accel_rad_s2 * h
            self.angle_rad += self.rate_rad_s * h
            self.impulse_Ns += self.thrust_N * h


#: Value of a plant parameter: a coefficient (a number) or a feather build option (the wake law, the
#: drag quadrature...: a name, an integer or a boolean; fmu_src.catalog.build_options("feather")).
PlantValue = float | int | bool | str


def feather_build_options() -> tuple[str, ...]:
    """The feather build options a plant parameter may set (the morphology has --morphology)."""
    return tuple(o for o in build_options("feather") if o != "morphology")


def _option_name(key: str) -> str | None:
    """The feather build option a "feather.NAME" (or bare NAME) key names, or None."""
    block, dot, name = key.partition(".")
    name = name if dot else block
    if dot and block != "feather":
        return None
    if name == "morphology":
        raise HILError(f"plant parameter {key!r}: the feather's morphology is chosen with --morphology "
                       "(spawn_emulator(morphology=...)), not as a hidden parameter")
    return name if name in build_options("feather") else None


def read_plant_parameters(path: str | Path | None, items: Sequence[str] = ()) -> dict[str, PlantValue]:
    """Plant parameters that differ from the defaults: a JSON object file ({"feather.drag_coeff":
    1.5, "feather.wake": "plate", ...}) and KEY=VALUE items (which win). Coefficients are finite
    numbers; feather build options (`feather_build_options`: the model's form) keep their value
    (a name, integer or boolean; the model checks it). The emulator never serves any of them
    over Modbus: a client has to measure them, which is what calibration is tested against."""
    parameters: dict[str, object] = {}
    if path is not None:
        try:
            loaded = json.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, ValueError, RecursionError) as exc:   # ValueError: bad JSON or not UTF-8
            raise HILError(f"--plant-parameters {path}: cannot read a JSON object "
                           f"({type(exc).__name__}: {str(exc)[:120]})") from None
        if not isinstance(loaded, dict):
            raise HILError(f"--plant-parameters {path}: must hold a JSON object of NAME: number")
        parameters.update(loaded)
    for item in items:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise HILError(f"--plant-set {item!r} must read NAME=VALUE")
        key, value = key.strip(), value.strip()
        # text from the command line: a build option's true/8 as the JSON file would give it
        parameters[key] = parse_value(value) if _option_name(key) else value
    checked: dict[str, PlantValue] = {}
    for key, value in parameters.items():
        if _option_name(key):
            if not isinstance(value, (str, int, bool)):
                raise HILError(f"plant build option {key!r} = {value!r} must be a name, an integer or "
                               "true/false (e.g. feather.wake=plate)")
            checked[key] = value
            continue
        try:   # a JSON true is not a coefficient, though Python would read it as 1
            number = math.nan if isinstance(value, bool) else float(value)
        except (TypeError, ValueError, OverflowError):
            number = math.nan
        if not math.isfinite(number):
            raise HILError(f"plant parameter {key!r} = {value!r} must be a finite number "
                           f"(or a feather build option: {', '.join(feather_build_options())})")
        checked[key] = number
    return checked


@dataclass(frozen=True)
class FmuPlantForm:
    """The FMU plant's hidden settings by role: the feather's build options (its model form),
    the feather's and the servo's coefficients."""

    feather_options: dict[str, PlantValue]
    feather: dict[str, float]
    servo: dict[str, float]


def fmu_plant_form(parameters: Mapping[str, PlantValue]) -> FmuPlantForm:
    """Split "feather.NAME" / "servo.NAME" keys (a bare NAME is the feather's) into build options
    and coefficients; the FMU plant's plan (featherstar.hil.fmu_plant.plant_plan) checks them."""
    form = FmuPlantForm({}, {}, {})
    for key, value in parameters.items():
        block, dot, name = key.partition(".")
        if not dot:
            block, name = "feather", key
        if block not in ("feather", "servo"):
            raise HILError(f"plant parameter {key!r}: the fmu plant has blocks 'feather' and 'servo'")
        if block == "feather" and _option_name(key):
            form.feather_options[name] = value
        elif block == "feather":
            form.feather[name] = float(value)
        else:
            form.servo[name] = float(value)
    return form


def flat_plate_plant(parameters: Mapping[str, float]) -> FlatPlatePlant:
    """A FlatPlatePlant with some of its coefficients (field names, e.g. c_n, c_a) changed."""
    names = {f.name for f in fields(FlatPlatePlant) if f.init}
    unknown = sorted(set(parameters) - names)
    if unknown:
        raise HILError(f"the flat-plate plant has no parameter(s) {', '.join(map(repr, unknown))}; "
                       f"it has: {', '.join(sorted(names))}")
    negative = [k for k, v in parameters.items() if v < 0]
    if negative:
        raise HILError(f"flat-plate plant parameter {negative[0]!r} = {parameters[negative[0]]} "
                       "must be >= 0")
    return FlatPlatePlant(**parameters)
