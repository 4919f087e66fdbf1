"""Drag and wake of a drag strip: a straight line of a rigid plate, along which the normal speed is affine.

The quadrature (`featherstar.fmu_src.drag_quadrature`) integrates −f |s| s along the line, s the
normal speed relative to the water and to the water the strip drags along (its wake, an option:
docs/model.md, "Wake memory"). `featherstar.fmu_src.chain` turns the result into its link's
wrench.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import casadi as ca

from .drag_quadrature import DragRule
from .fluid import quadratic_drag_N, wake_decay


@dataclass(frozen=True)
class DragStrip:
    """A straight line of a plate from `start` to `end` (each (along_m, across_m), as a
    PlatePoint's) that carries the drag of the strip of plate around it: −∫₀¹ f(along(t)) |s| s dt n,
    s the normal speed relative to the water, f = `drag_factor_kg_m(along_m)` = ½ ρ C_d × the
    strip's area. On a rigid plate s is affine along the line (`featherstar.fmu_src.drag_quadrature`)."""

    start: tuple[ca.SX, ca.SX]
    end: tuple[ca.SX, ca.SX]
    drag_factor_kg_m: Callable[[ca.SX], ca.SX]
    wake: StripWake | None = None


@dataclass(frozen=True)
class StripWake:
    """The wake of a drag strip: the normal speeds u_a, u_b (states) of the water dragged along at
    the fractions t_a, t_b of the line (its mass points); u is affine between and beyond them, so s
    stays affine along the line."""

    at: tuple[float, float]
    speeds_m_s: tuple[ca.SX, ca.SX]


@dataclass(frozen=True)
class WakeLaw:
    """`law` (featherstar.fmu_src.fluid.WAKE_LAWS), forcing B, decay length γ in widths of `width_m`."""

    law: str
    forcing: ca.SX
    decay_widths: ca.SX
    width_m: ca.SX


@dataclass(frozen=True)
class StripDrag:
    """What a strip's drag asks of its link: the planar wrench about the link's origin, in the
    link's frame (moment_z, force_along, force_normal; the negative of the drag's, as the point
    wrenches of `featherstar.fmu_src.chain`), the moment about a flap's hinge, the drag's ŷ part,
    and the wake: u̇ of its states, its kinetic energy and the power lost in the water."""

    wrench: ca.SX
    fold_moment: ca.SX
    drag_y_N: ca.SX
    wake_rates: list[ca.SX]
    wake_energy_J: ca.SX
    dissipation_W: ca.SX


def _vec(*components: ca.SX) -> ca.SX:
    return ca.vertcat(*components)


def strip_drag(strip: DragStrip, rule: DragRule, wake: WakeLaw | None, normal: ca.SX,
               kinematics: Callable[[ca.SX, ca.SX], tuple[ca.SX, ca.SX]], body_velocity: ca.SX,
               up: ca.SX) -> StripDrag:
    """The strip's drag, as the link needs it, and its wake. `kinematics(along, across)` gives a
    point's offset from the link origin and its velocity, in the link frame, where `normal` is
    the plate's normal, `body_velocity` what the body's speed adds to every point's velocity through
    the water (U ŷ) and `up` is ŷ.

    The wake's states are nodal values of an affine u(t) = Σ_i u_i φ_i(t). The drag's reaction on
    the water, F_i = ∫ f |s| s φ_i dt with the drag's own quadrature, drives node i, whose water
    mass is m_i = D_i w / B (D_i = ∫ f φ_i dt): m_i u̇_i = F_i − m_i decay_i / (γ w). Then the drag's
    power on the plate is exactly −[∫ f |s|³ dt + d/dt Σ ½ m_i u_i² + Σ m_i u_i decay_i / (γ w)].
    As the plate turns, the dragged water keeps its direction: its normal component changes only at
    second order in the angle (ṅ ⟂ n), so u̇ has no rotation term, on spine and flap alike."""

    def normal_speed(along, across):
        offset, velocity = kinematics(along, across)
        return offset, ca.dot(normal, velocity + body_velocity)

    if strip.wake is not None:
        (t_a, t_b), (u_a, u_b) = strip.wake.at, strip.wake.speeds_m_s
        shapes = (lambda t: (t_b - t) / (t_b - t_a), lambda t: (t - t_a) / (t_b - t_a))
    else:
        u_a = u_b = ca.SX(0)
        shapes = (lambda t: 1.0 - t, lambda t: t)

    def wake_speed(t):
        return u_a * shapes[0](t) + u_b * shapes[1](t)

    (a0, c0), (a1, c1) = strip.start, strip.end

    def point(t):
        return a0 + t * (a1 - a0), c0 + t * (c1 - c0)

    _, speed_start = normal_speed(a0, c0)
    _, speed_end = normal_speed(a1, c1)
    wrench, fold_moment, drag_y = ca.SX.zeros(3), ca.SX(0), ca.SX(0)
    reactions, dissipation = [ca.SX(0), ca.SX(0)], ca.SX(0)
    for t, weight in rule.nodes(speed_start - wake_speed(0.0), speed_end - wake_speed(1.0)):
        along, across = point(t)
        offset, speed = normal_speed(along, across)
        relative = speed - wake_speed(t)
        factor = weight * strip.drag_factor_kg_m(along)
        drag = quadratic_drag_N(factor, relative, normal)
        wrench = wrench - _vec(offset[0] * drag[1] - offset[1] * drag[0], drag[0], drag[1])
        fold_moment = fold_moment + across * ca.dot(normal, drag)
        drag_y = drag_y + ca.dot(drag, up)
        if strip.wake is not None:
            for i in (0, 1):
                reactions[i] = reactions[i] + factor * ca.fabs(relative) * relative * shapes[i](t)
            dissipation = dissipation + factor * ca.fabs(relative) ** 3
    rates, energy = [], ca.SX(0)
    if strip.wake is not None:
        for i, (t_i, u_i) in enumerate(zip(strip.wake.at, strip.wake.speeds_m_s)):
            along, across = point(t_i)
            _, speed = normal_speed(along, across)
            decay = wake_decay(wake.law, u_i, speed - u_i, speed)
            share = (t_b - 0.5) / (t_b - t_a) if i == 0 else (0.5 - t_a) / (t_b - t_a)  # ∫₀¹ φ_i dt
            node_drag = strip.drag_factor_kg_m(along) * share
            per_drag = reactions[i] / ca.if_else(node_drag > 0, node_drag, 1.0)  # s|s| of a uniform strip
            rates.append((wake.forcing * per_drag - decay / wake.decay_widths) / wake.width_m)
            water_mass = ca.if_else(wake.forcing > 0, node_drag * wake.width_m / wake.forcing, 0)
            energy = energy + 0.5 * water_mass * u_i**2
            dissipation = dissipation + water_mass * u_i * decay / (wake.decay_widths * wake.width_m)
    return StripDrag(wrench, fold_moment, drag_y, rates, energy, dissipation)
