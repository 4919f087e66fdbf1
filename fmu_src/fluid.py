"""Strip-theory fluid forces on the feather's quadrature points, derived from the fluid's energy.

Each point p carries an added mass m_a,p acting along its surface normal n_p. The fluid's kinetic
energy is T_f = ½ Σ_p m_a,p v_n,p², v_n,p = n_p·w_p, with w_p the point's velocity relative to the
water at rest (the body speed U included). Lagrange's equations give the generalized fluid force

    Q_f = −d/dt(∂T_f/∂Ġ) + ∂T_f/∂G = −Σ_p m_a [v̇_n G_pᵀn + v_n G_pᵀṅ] + Σ_p m_a v_n (∂n_p/∂G)ᵀ w_p,

where G_p = ∂r_p/∂G. The last sum is the Munk couple (it turns a plate moving obliquely
broadside); without it the force would still not conserve energy. For a point on a plate turning
at Ω, ṅ = Ω × n and (∂n/∂G)ᵀ w = (∂Ω/∂Ġ)ᵀ (n × w): the Munk term is the couple m_a v_n (n × w) on
the plate, which is how `featherstar.fmu_src.chain` applies it. The resultant force on the
feather is −d/dt Σ_p m_a v_n n: the rate of change of the fluid impulse, whose mean over a
periodic motion is exactly zero. The Morison form −m_a (n·r̈) n, written for a body that does not
rotate, lacks both velocity-product terms and manufactures a mean thrust on a bending feather
(docs/model.md).

Drag is quadratic in the normal relative velocity, −½ρ C_d A |v_n| v_n n, with C_d either a
constant or the oscillatory-flow plate coefficient of Luhar & Nepf (2016).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca

#: Keulegan–Carpenter number below which the oscillatory drag fit is held constant: the plate
#: data it was fitted to (Keulegan & Carpenter 1958, Sarpkaya & O'Keefe 1996) start near KC = 2,
#: and 10·KC^(−1/3) diverges as KC → 0 (the drag force itself vanishes there with the velocity).
LOWEST_FITTED_KC = 2.0
#: The fit's large-KC floor (steady separated flow past a plate is 1.2; oscillating plates shed
#: into their own wake and keep more drag).
LARGE_KC_DRAG_COEFF = 1.95


def dnv_added_mass_coeff(aspect_ratio: ca.SX) -> ca.SX:
    """3D added-mass coefficient of a rectangular plate, b/a >= 1 (DNV-RP-C205 Table A-2, fitted
    to 0.12 %: 1 → 0.579, 2 → 0.757, 10 → 0.947, ∞ → 1)."""
    return 1.0 - 0.63479 / (aspect_ratio**1.06890 + 0.50706)


def oscillatory_drag_coeff(keulegan_carpenter: ca.SX) -> ca.SX:
    """Normal drag coefficient of a flat plate in oscillatory flow, C_d = max(10·KC^(−1/3), 1.95)
    (Luhar & Nepf, J. Fluids Struct. 61, 2016), with KC held at LOWEST_FITTED_KC below it."""
    kc = ca.fmax(keulegan_carpenter, LOWEST_FITTED_KC)
    return ca.fmax(10.0 * kc ** (-1.0 / 3.0), LARGE_KC_DRAG_COEFF)


def stroke_keulegan_carpenter(span_m: ca.SX, stroke_amplitude_rad: ca.SX, width_m: ca.SX) -> ca.SX:
    """KC = 2πa/w of a point at distance `span_m` from the root, whose displacement amplitude under
    a root stroke of `stroke_amplitude_rad` (peak to peak) is a = span·A/2."""
    return math.pi * span_m * stroke_amplitude_rad / width_m


@dataclass(frozen=True)
class FluidLoads:
    """What the fluid does to one point besides the added-mass force −m_a (n·a) n, which
    belongs to the mass matrix. Vectors are in whatever frame the arguments were given."""

    normal_speed_m_s: ca.SX  # v_n = n·w
    impulse_rate_N: ca.SX  # m_a [(ṅ·w) n + v_n ṅ]: the rest of d/dt(m_a v_n n)
    munk_couple_Nm: ca.SX  # m_a v_n (n × w), the couple the fluid applies (turns a plate broadside)


def fluid_loads(added_mass_kg: ca.SX, normal: ca.SX, normal_rate: ca.SX, relative_velocity: ca.SX) -> FluidLoads:
    """Velocity-product fluid force and Munk couple of a point whose normal n turns at
    `normal_rate` (ṅ = Ω × n) and moves at w = `relative_velocity` through still water."""
    normal_speed = ca.dot(normal, relative_velocity)
    return FluidLoads(
        normal_speed_m_s=normal_speed,
        impulse_rate_N=added_mass_kg * (ca.dot(normal_rate, relative_velocity) * normal + normal_speed * normal_rate),
        munk_couple_Nm=added_mass_kg * normal_speed * ca.cross(normal, relative_velocity),
    )


def quadratic_drag_N(drag_factor_kg_m: ca.SX, normal_speed_m_s: ca.SX, normal: ca.SX) -> ca.SX:
    """Normal drag −f |s| s n of a piece of plate with drag factor f = ½ ρ C_d A moving at normal
    speed s relative to the water."""
    return -drag_factor_kg_m * ca.fabs(normal_speed_m_s) * normal_speed_m_s * normal


#: Wake memory (issue 26, item 1): each strip drags along water whose normal velocity u relaxes as
#:     w u̇ = B F/D − decay(u, s, v)/γ,   s = v_n − u,   drag −½ ρ C_0 A |s| s,
#: (F/D = s|s| for a uniform strip; w the feather's width) under one of three decay laws: the
#: plate leaves its wake ("relative", u|s|), the wake convects itself away ("self", u|u|), the wake
#: is left behind at the plate's speed ("plate", u|v_n|).
WAKE_LAWS = ("relative", "self", "plate")

#: (C_0, B, γ in widths) per law, fitted jointly (`python bench/wake_memory.py`, least squares in
#: log C_d, docs/results/wake_memory.json) to the Fourier-averaged drag coefficient of a plate
#: oscillating sinusoidally at KC 2–400 (Luhar & Nepf 2016's max(10 KC^(−1/3), 1.95), itself a fit
#: to Keulegan & Carpenter 1958 and Sarpkaya & O'Keefe 1996) and to the steady plate's 1.2 (Hoerner
#: 1965) as one more point. Nothing is fitted to the paper.
WAKE_CONSTANTS: dict[str, tuple[float, float, float]] = {
    "relative": (6.7958, 0.27234, 3.8267),
    "self": (6.5631, 0.23380, 4.0848),
    "plate": (6.6512, 0.26223, 7.6475),
}


def wake_decay(law: str, wake_speed: ca.SX, relative_speed: ca.SX, normal_speed: ca.SX) -> ca.SX:
    """decay(u, s, v) of `law` (m²/s²): u|s|, u|u| or u|v|. Its product with u is never negative,
    so the decay only dissipates the wake's energy."""
    scale = {"relative": relative_speed, "self": wake_speed, "plate": normal_speed}[law]
    return wake_speed * ca.fabs(scale)
