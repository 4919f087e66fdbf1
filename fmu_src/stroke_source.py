"""Signal sources as models: the paper's 4-phase stroke and constant outputs.

A scene's stroke controller and constant blocks are Python blocks; exported to SSP
(featherstar.cosim.ssp.export) they become FMUs of these models, so that a package is FMUs only
and other FMI/SSP tools (Ecos, libcosim, OMSimulator) can run it. Models here are explicit ODEs
without a time input, so each source carries its clock as a state, time_s' = 1 from 0 (the
run's start): outputs are functions of that clock and the parameters.

`root_motion_symbolic` is the stroke itself (featherstar.cosim.swimmer.stroke evaluates the same
expressions for the master and the monolithic reference).
"""
from __future__ import annotations

import sys
from typing import Mapping

import casadi as ca

from .errors import ModelError
from .model import Model, Parameter, Variable

#: the widest range a double allows: a constant's value is whatever the scene says
_ANY = (-sys.float_info.max, sys.float_info.max)
_CLOCK = Variable("time_s", "s", "time since the start of the run (the source's clock: time_s' = 1)", 0.0)


def root_motion_symbolic(
    t: ca.SX, t_up: ca.SX, t_hold_up: ca.SX, t_down: ca.SX, t_hold_down: ca.SX, amplitude_rad: ca.SX
) -> tuple[ca.SX, ca.SX, ca.SX]:
    """Angle, rate and acceleration of the 4-phase minimum-jerk stroke at t, as CasADi
    expressions (featherstar.cosim.swimmer.stroke describes the stroke). Stroke times may be symbols."""
    period = t_up + t_hold_up + t_down + t_hold_down
    phase = ca.fmod(t, period)
    rising = phase < t_up
    falling = ca.logic_and(phase >= t_up + t_hold_up, phase < t_up + t_hold_up + t_down)
    tau = ca.if_else(rising, phase / t_up, (phase - t_up - t_hold_up) / t_down)
    tau = ca.fmin(ca.fmax(tau, 0), 1)
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    ds = 30 * tau**2 * (1 - 2 * tau + tau**2)
    dds = 60 * tau * (1 - 3 * tau + 2 * tau**2)
    duration = ca.if_else(rising, t_up, t_down)
    sign = ca.if_else(rising, 1, -1)
    moving = ca.logic_or(rising, falling)
    held = ca.if_else(phase < t_up + t_hold_up + t_down, 0.5, -0.5) * amplitude_rad
    angle = ca.if_else(moving, sign * amplitude_rad * (s - 0.5), held)
    rate = ca.if_else(moving, sign * amplitude_rad * ds / duration, 0)
    accel = ca.if_else(moving, sign * amplitude_rad * dds / duration**2, 0)
    return angle, rate, accel


def stroke_source_model() -> Model:
    """The stroke controller as a model: parameters the four times and the amplitude (peak to
    peak, rad), outputs the root angle, rate and acceleration of featherstar's `stroke` block."""
    x, u, p = ca.SX.sym("x", 1), ca.SX.sym("u", 0), ca.SX.sym("p", 5)
    angle, rate, accel = root_motion_symbolic(x[0], p[0], p[1], p[2], p[3], p[4])
    return Model(
        name="stroke_source",
        description="featherstar's 4-phase minimum-jerk stroke (rise, hold up, fall, hold down) as a signal source",
        states=(_CLOCK,),
        inputs=(),
        parameters=(
            Parameter("t_up_s", 0.25, "s", 0.0, 1e6, "upstroke (rise) time", exclusive_minimum=True),
            Parameter("t_hold_up_s", 0.5, "s", 0.0, 1e6, "hold at the top"),
            Parameter("t_down_s", 0.25, "s", 0.0, 1e6, "downstroke (fall) time", exclusive_minimum=True),
            Parameter("t_hold_down_s", 0.5, "s", 0.0, 1e6, "hold at the bottom"),
            Parameter("amplitude_rad", 1.0471975511965976, "rad", 0.0, 3.141592653589793,
                      "peak-to-peak amplitude, centred on zero", exclusive_minimum=True),
        ),
        outputs=(
            Variable("angle_rad", "rad", "commanded root angle"),
            Variable("rate_rad_s", "rad/s", "commanded root rate"),
            Variable("accel_rad_s2", "rad/s2", "commanded root acceleration"),
        ),
        x=x, u=u, p=p, xdot=ca.SX(1.0), y=ca.vertcat(angle, rate, accel),
    )


def constant_source_model(outputs: Mapping[str, str]) -> Model:
    """Constant outputs {name: unit}, each the value of the parameter `<name>_value`."""
    if not outputs:
        raise ModelError("a constant source needs at least one output")
    names = [str(name) for name in outputs]
    x, u, p = ca.SX.sym("x", 1), ca.SX.sym("u", 0), ca.SX.sym("p", len(names))
    return Model(
        name="constant_source",
        description="constant outputs, each set by its parameter <output>_value",
        states=(_CLOCK,),
        inputs=(),
        parameters=tuple(Parameter(f"{name}_value", 0.0, str(outputs[name]), *_ANY, f"the value of {name}")
                         for name in names),
        outputs=tuple(Variable(name, str(outputs[name]), f"constant output {name}") for name in names),
        x=x, u=u, p=p, xdot=ca.SX(1.0), y=p,
        options={"outputs": tuple((name, str(outputs[name])) for name in names)},
    )
