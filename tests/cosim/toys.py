"""Small fmu_src Models for the master's tests: a two-mass oscillator split in two blocks
(the classic co-simulation benchmark: force/displacement coupling) and feedthrough gains."""
from __future__ import annotations

import casadi as ca

from featherstar.fmu_src.model import Model, Parameter, Variable


def oscillator_a(x0: float = 1.0) -> Model:
    """Mass 1 on a wall spring; input: the coupling force; outputs: position and velocity."""
    x, v, f = ca.SX.sym("x"), ca.SX.sym("v"), ca.SX.sym("f")
    params = (
        Parameter("mass_kg", 1.0, "kg", 0.0, 100.0, "mass", True),
        Parameter("stiffness_N_m", 10.0, "N/m", 0.0, 1e6, "wall spring"),
        Parameter("damping_Ns_m", 0.1, "N.s/m", 0.0, 1e3, "wall damper"),
    )
    p = ca.SX.sym("p", 3)
    m, k, d = p[0], p[1], p[2]
    return Model(
        name="osc_a", description="mass 1",
        states=(Variable("x_m", "m", "position", x0), Variable("v_m_s", "m/s", "velocity")),
        inputs=(Variable("force_N", "N", "coupling force"),),
        parameters=params,
        outputs=(Variable("position_m", "m", "position"), Variable("velocity_m_s", "m/s", "velocity")),
        x=ca.vertcat(x, v), u=f, p=p,
        xdot=ca.vertcat(v, (-k * x - d * v + f) / m),
        y=ca.vertcat(x, v),
    )


def oscillator_b() -> Model:
    """Mass 2 tied to mass 1 by a spring-damper; input: mass 1's motion; output: the coupling
    force on mass 1 (direct feedthrough of the inputs)."""
    x, v = ca.SX.sym("x"), ca.SX.sym("v")
    x1, v1 = ca.SX.sym("x1"), ca.SX.sym("v1")
    params = (
        Parameter("mass_kg", 1.0, "kg", 0.0, 100.0, "mass", True),
        Parameter("stiffness_N_m", 10.0, "N/m", 0.0, 1e6, "wall spring"),
        Parameter("damping_Ns_m", 0.1, "N.s/m", 0.0, 1e3, "wall damper"),
        Parameter("coupling_stiffness_N_m", 100.0, "N/m", 0.0, 1e6, "coupling spring"),
        Parameter("coupling_damping_Ns_m", 1.0, "N.s/m", 0.0, 1e3, "coupling damper"),
    )
    p = ca.SX.sym("p", 5)
    m, k, d, kc, dc = (p[i] for i in range(5))
    force = kc * (x - x1) + dc * (v - v1)
    return Model(
        name="osc_b", description="mass 2",
        states=(Variable("x_m", "m", "position"), Variable("v_m_s", "m/s", "velocity")),
        inputs=(Variable("other_position_m", "m", "mass 1 position"),
                Variable("other_velocity_m_s", "m/s", "mass 1 velocity")),
        parameters=params,
        outputs=(Variable("force_N", "N", "coupling force on mass 1"), Variable("position_m", "m", "position")),
        x=ca.vertcat(x, v), u=ca.vertcat(x1, v1), p=p,
        xdot=ca.vertcat(v, (-k * x - d * v - force) / m),
        y=ca.vertcat(force, x),
    )


def gain(gain: float = 0.5, offset: float = 1.0) -> Model:
    """y = gain*u + offset (direct feedthrough), with one decaying dummy state."""
    x, u = ca.SX.sym("x"), ca.SX.sym("u")
    p = ca.SX.sym("p", 2)
    return Model(
        name="gain", description="feedthrough gain",
        states=(Variable("dummy", "1", "decays", 1.0),),
        inputs=(Variable("u", "1", "input"),),
        parameters=(Parameter("gain", gain, "1", -1e6, 1e6, "gain"),
                    Parameter("offset", offset, "1", -1e6, 1e6, "offset")),
        outputs=(Variable("y", "1", "output"),),
        x=x, u=u, p=p, xdot=-x, y=p[0] * u + p[1],
    )


def blowup(x0: float = 1.0) -> Model:
    """x' = x² (+ input): finite-time blow-up at t = 1/x0."""
    x, u = ca.SX.sym("x"), ca.SX.sym("u")
    p = ca.SX.sym("p", 1)
    return Model(
        name="blowup", description="x' = x^2",
        states=(Variable("x", "1", "state", x0),),
        inputs=(Variable("u", "1", "input"),),
        parameters=(Parameter("scale", 1.0, "1", 0.0, 10.0, "growth scale"),),
        outputs=(Variable("y", "1", "x"),),
        x=x, u=u, p=p, xdot=p[0] * x**2 + u, y=x,
    )
