"""The two-feather robot: servo crank → four-bar → both feather roots, and the body on its rail.

Kinematics are exact derivatives of the closed-form rocker angle: ω4 = θ4'(θ2) ω2 and
α4 = θ4''(θ2) ω2² + θ4'(θ2) α2. An ideal linkage conserves power, so the servo feels the sum of
the feather root torques times θ4'. The body (mass plus added mass plus the feathers' surge mass)
is pushed by both feathers' thrust and held back by quadratic body drag, rail Coulomb friction (smoothed with tanh) and
viscous rail friction (physics spec §6; the paper gives no robot parameters, these are estimates).
"""
from __future__ import annotations

import math
from typing import Mapping

import casadi as ca

from .fourbar import check_linkage, rocker_angle
from .model import Model, Parameter, Variable


def robot_model() -> Model:
    parameters = (
        Parameter("crank_m", 0.025, "m", 0.0, 1.0, "four-bar crank a (servo horn)", True),
        Parameter("coupler_m", 0.062, "m", 0.0, 1.0, "four-bar coupler b", True),
        Parameter("rocker_m", 0.03, "m", 0.0, 1.0, "four-bar rocker c (feather root lever)", True),
        Parameter("ground_m", 0.06, "m", 0.0, 1.0, "four-bar ground link d", True),
        Parameter("crank_neutral_rad", math.pi / 2, "rad", 0.0, math.pi, "crank angle at servo zero"),
        Parameter("crank_range_rad", math.radians(45.0), "rad", 0.0, math.pi, "servo travel checked for conditioning (±)"),
        Parameter("body_mass_kg", 0.4, "kg", 0.0, 100.0, "robot mass", True),
        Parameter("body_added_mass_kg", 0.2, "kg", 0.0, 100.0, "added mass along the rail"),
        Parameter("body_drag_coeff", 1.0, "1", 0.0, 10.0, "body drag coefficient"),
        Parameter("body_frontal_area_m2", 4e-3, "m2", 0.0, 1.0, "body frontal area"),
        Parameter("water_density_kg_m3", 1000.0, "kg/m3", 0.0, 2000.0, "fluid density", True),
        Parameter("rail_coulomb_N", 2e-3, "N", 0.0, 10.0, "rail dry friction"),
        Parameter("rail_coulomb_speed_m_s", 1e-3, "m/s", 0.0, 1.0, "speed over which dry friction builds up", True),
        Parameter("rail_viscous_Ns_m", 0.02, "N.s/m", 0.0, 100.0, "rail viscous friction"),
    )
    p = ca.SX.sym("p", len(parameters))
    P = {par.name: p[i] for i, par in enumerate(parameters)}
    a, b, c, d = P["crank_m"], P["coupler_m"], P["rocker_m"], P["ground_m"]
    position, speed = ca.SX.sym("x"), ca.SX.sym("v")
    crank, crank_rate, crank_accel = ca.SX.sym("th2"), ca.SX.sym("w2"), ca.SX.sym("a2")
    thrust_left, thrust_right, torque_left, torque_right = (ca.SX.sym(n) for n in ("TL", "TR", "QL", "QR"))
    surge_left, surge_right = ca.SX.sym("ML"), ca.SX.sym("MR")

    theta2 = P["crank_neutral_rad"] + crank
    theta4 = rocker_angle(theta2, a, b, c, d)
    gain = ca.jacobian(theta4, crank)
    gain_slope = ca.jacobian(gain, crank)
    root_angle = theta4 - rocker_angle(P["crank_neutral_rad"], a, b, c, d)
    root_rate = gain * crank_rate
    root_accel = gain_slope * crank_rate**2 + gain * crank_accel

    drag = 0.5 * P["water_density_kg_m3"] * P["body_drag_coeff"] * P["body_frontal_area_m2"] * ca.fabs(speed) * speed
    friction = P["rail_coulomb_N"] * ca.tanh(speed / P["rail_coulomb_speed_m_s"]) + P["rail_viscous_Ns_m"] * speed
    # The feathers' thrust is their force on a root that does not accelerate; the rest of the root
    # force, −surge_mass·U̇ (their structure and the water their surfaces push along y), joins the
    # body's inertia. Fed back as a thrust term instead, it would close an algebraic loop and, with
    # U̇ left out, put a spurious mean force on the body (docs/model.md, Robot).
    inertia = P["body_mass_kg"] + P["body_added_mass_kg"] + surge_left + surge_right
    body_accel = (thrust_left + thrust_right - drag - friction) / inertia

    def linkage_closes(values: Mapping[str, float]) -> None:
        check_linkage(values["crank_m"], values["coupler_m"], values["rocker_m"], values["ground_m"],
                      values["crank_neutral_rad"], values["crank_range_rad"])

    return Model(
        name="robot",
        description="four-bar linkage and robot body on the rail",
        states=(
            Variable("body_x_m", "m", "body position along the rail"),
            Variable("body_v_m_s", "m/s", "body speed along the rail"),
        ),
        inputs=(
            Variable("crank_angle_rad", "rad", "servo angle (0 = neutral)"),
            Variable("crank_rate_rad_s", "rad/s", "servo rate"),
            Variable("crank_accel_rad_s2", "rad/s2", "servo acceleration"),
            Variable("thrust_left_N", "N", "left feather thrust along the rail"),
            Variable("thrust_right_N", "N", "right feather thrust along the rail"),
            Variable("root_torque_left_Nm", "N.m", "left feather root torque"),
            Variable("root_torque_right_Nm", "N.m", "right feather root torque"),
            Variable("surge_mass_left_kg", "kg", "left feather's mass along the rail, structure plus added mass", 0.0),
            Variable("surge_mass_right_kg", "kg", "right feather's mass along the rail, structure plus added mass", 0.0),
        ),
        parameters=parameters,
        outputs=(
            Variable("root_angle_rad", "rad", "feather root angle (0 at servo neutral)"),
            Variable("root_rate_rad_s", "rad/s", "feather root rate"),
            Variable("root_accel_rad_s2", "rad/s2", "feather root acceleration"),
            Variable("servo_load_torque_Nm", "N.m", "torque the feathers demand at the servo"),
            Variable("body_position_m", "m", "body position along the rail"),
            Variable("body_speed_m_s", "m/s", "body speed along the rail"),
            Variable("feather_force_left_N", "N",
                     "force along the rail the left feather puts on the accelerating body (its load-cell reading)"),
        ),
        x=ca.vertcat(position, speed),
        u=ca.vertcat(crank, crank_rate, crank_accel, thrust_left, thrust_right, torque_left, torque_right,
                     surge_left, surge_right),
        p=p,
        xdot=ca.vertcat(speed, body_accel),
        y=ca.vertcat(root_angle, root_rate, root_accel, gain * (torque_left + torque_right), position, speed,
                     thrust_left - surge_left * body_accel),
        constraints=(linkage_closes,),
    )
