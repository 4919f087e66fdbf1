"""Strip-theory fluid forces on the feather's quadrature points, derived from the fluid's energy.

Each point p carries an added mass m_a,p acting along its surface normal n_p. The fluid's kinetic
energy is T_f = ½ Σ_p m_a,p v_n,p², v_n,p = n_p·w_p, with w_p the point's velocity relative to the
water at rest (the body speed U included). Lagrange's equations give the generalized fluid force

    Q_f = −d/dt(∂T_f/∂Ġ) + ∂T_f/∂G = −Σ_p m_a [v̇_n G_pᵀn + v_n G_pᵀṅ] + Σ_p m_a v_n (∂n_p/∂G)ᵀ w_p,

where G_p = ∂r_p/∂G. The last sum is the Munk couple (it turns a plate moving obliquely
broadside); without it the force would still not conserve energy. The resultant force on the
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


@dataclass
class Point:
    """A quadrature point of the feather, every field a CasADi expression."""

    position: ca.SX  # 3-vector, root frame
    normal: ca.SX  # unit 3-vector
    mass_kg: ca.SX
    added_mass_kg: ca.SX
    area_m2: ca.SX
    volume_m3: ca.SX
    drag_coeff: ca.SX


@dataclass
class PointDynamics:
    """One point's share of the generalized equations over G = (Q, θ0), and what the load cell
    needs. Accelerations are split as r̈ = J_G Ġ̇ with the root's part known: a = J_Q Q̈ + a_known."""

    mass_matrix: ca.SX  # (nG, nG): m_p J_Gᵀ J_G + m_a (J_Gᵀ n)(J_Gᵀ n)ᵀ
    bias: ca.SX  # (nG,): inertial and fluid-reactive forces not proportional to Q̈
    applied: ca.SX  # (nG,): generalized drag and buoyancy
    jacobian_q: ca.SX  # (3, nQ)
    known_accel: ca.SX  # (3,)
    velocity: ca.SX  # (3,) relative to the root frame
    relative_velocity: ca.SX  # (3,) relative to the water (body speed included)
    normal_rate: ca.SX  # (3,)
    drag: ca.SX  # (3,)
    point: Point

    def momentum_rate(self, q_accel: ca.SX) -> ca.SX:
        """d/dt of the structure's momentum plus the fluid impulse m_a v_n n carried by this point."""
        accel = self.jacobian_q @ q_accel + self.known_accel
        n, w = self.point.normal, self.relative_velocity
        normal_speed_rate = ca.dot(n, accel) + ca.dot(self.normal_rate, w)
        return self.point.mass_kg * accel + self.point.added_mass_kg * (
            normal_speed_rate * n + ca.dot(n, w) * self.normal_rate)

    def momentum(self) -> ca.SX:
        """Structure momentum plus fluid impulse of this point (root frame velocities)."""
        n = self.point.normal
        return self.point.mass_kg * self.velocity + self.point.added_mass_kg * ca.dot(n, self.relative_velocity) * n

    def kinetic_energy(self) -> ca.SX:
        """Structure plus fluid kinetic energy, in the root's frame (the body speed excluded)."""
        n = self.point.normal
        return 0.5 * self.point.mass_kg * ca.dot(self.velocity, self.velocity) + 0.5 * self.point.added_mass_kg * ca.dot(
            n, self.velocity) ** 2


def point_dynamics(
    point: Point, coords: ca.SX, coord_rates: ca.SX, n_free: int, root_accel: ca.SX, flow_speed_m_s: ca.SX,
    water_density: ca.SX, gravity_force: ca.SX,
) -> PointDynamics:
    """Lagrangian contributions of `point`. `coords` is G = (Q, θ0): the first `n_free` are free,
    the last is the prescribed root angle with acceleration `root_accel`. `gravity_force` is the
    point's net weight-plus-buoyancy vector per unit volume."""
    jac = ca.jacobian(point.position, coords)
    velocity = jac @ coord_rates
    relative = velocity + flow_speed_m_s * ca.DM([0.0, 1.0, 0.0])
    convective = ca.jtimes(velocity, coords, coord_rates)  # J̇ Ġ
    known_accel = jac[:, n_free] * root_accel + convective
    n = point.normal
    normal_rate = ca.jtimes(n, coords, coord_rates)
    normal_speed = ca.dot(n, relative)
    jac_n = jac.T @ n
    m, m_a = point.mass_kg, point.added_mass_kg
    bias = m * (jac.T @ known_accel) + m_a * (
        (ca.dot(n, known_accel) + ca.dot(normal_rate, relative)) * jac_n
        + normal_speed * (jac.T @ normal_rate)
        - normal_speed * (ca.jacobian(n, coords).T @ relative)  # the Munk couple
    )
    drag = -0.5 * water_density * point.drag_coeff * point.area_m2 * ca.fabs(normal_speed) * normal_speed * n
    applied = jac.T @ (drag + point.volume_m3 * gravity_force)
    return PointDynamics(
        mass_matrix=m * (jac.T @ jac) + m_a * (jac_n @ jac_n.T), bias=bias, applied=applied,
        jacobian_q=jac[:, :n_free], known_accel=known_accel, velocity=velocity, relative_velocity=relative,
        normal_rate=normal_rate, drag=drag, point=point,
    )
