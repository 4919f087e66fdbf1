"""Position servo whose speed limit falls with load torque (MG996R-like defaults).

The commanded speed is the position error over τ_s, saturated smoothly (tanh) at
ω_max = ω0·max(1 − |τ_load|/τ_stall, floor): the DC-motor torque–speed line of physics spec §5.
The rotor follows the commanded speed with the mechanical time constant τ_ω, so angle, rate and
acceleration are all continuous and the acceleration can drive a feather's added mass. The load
torque enters through a first-order filter (the motor current's lag), which also keeps the
servo → feather → servo path free of an algebraic loop. The speed floor (default 2 % of ω0)
keeps a stalled servo creeping instead of freezing the ODE at a 0/0.
"""
from __future__ import annotations

import casadi as ca

from .model import Model, Parameter, Variable


def servo_model() -> Model:
    parameters = (
        Parameter("no_load_speed_rad_s", 6.2, "rad/s", 0.0, 100.0, "ω0 (MG996R: 0.17 s/60°)", True),
        Parameter("stall_torque_Nm", 1.1, "N.m", 0.0, 100.0, "τ_stall (MG996R: 0.92–1.27 N·m)", True),
        Parameter("position_time_constant_s", 0.03, "s", 0.0, 1.0, "τ_s: position loop (20–50 ms)", True),
        Parameter("rate_time_constant_s", 0.01, "s", 0.0, 1.0, "τ_ω: rotor follows commanded speed", True),
        Parameter("load_filter_time_constant_s", 0.005, "s", 0.0, 1.0, "lag of the sensed load torque", True),
        Parameter("stall_speed_floor", 0.02, "1", 0.0, 1.0, "speed limit floor as a share of ω0", True),
    )
    p = ca.SX.sym("p", len(parameters))
    omega0, tau_stall, tau_s, tau_w, tau_f, floor = (p[i] for i in range(6))
    angle, rate, load = ca.SX.sym("angle"), ca.SX.sym("rate"), ca.SX.sym("load")
    setpoint, load_torque = ca.SX.sym("setpoint"), ca.SX.sym("load_torque")
    speed_limit = omega0 * ca.fmax(1 - ca.fabs(load) / tau_stall, floor)
    commanded = speed_limit * ca.tanh((setpoint - angle) / (tau_s * speed_limit))
    accel = (commanded - rate) / tau_w
    return Model(
        name="servo",
        description="position servo with a load-dependent speed limit",
        states=(
            Variable("shaft_angle_rad", "rad", "output shaft angle"),
            Variable("shaft_rate_rad_s", "rad/s", "output shaft rate"),
            Variable("sensed_load_Nm", "N.m", "filtered load torque"),
        ),
        inputs=(
            Variable("setpoint_rad", "rad", "commanded angle"),
            Variable("load_torque_Nm", "N.m", "torque the load demands at the shaft"),
        ),
        parameters=parameters,
        outputs=(
            Variable("angle_rad", "rad", "shaft angle"),
            Variable("rate_rad_s", "rad/s", "shaft rate"),
            Variable("accel_rad_s2", "rad/s2", "shaft acceleration"),
        ),
        x=ca.vertcat(angle, rate, load),
        u=ca.vertcat(setpoint, load_torque),
        p=p,
        xdot=ca.vertcat(rate, accel, (load_torque - load) / tau_f),
        y=ca.vertcat(angle, rate, accel),
    )
