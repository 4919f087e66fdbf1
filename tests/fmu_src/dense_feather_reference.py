"""The feather's dynamics as they were formulated before the O(N) chain solve (commit 32dc597):
every point's position an expression of (Q, θ0), the dense mass matrix from exact Jacobians and a
symbolic LDLᵀ solve. A test reference only: `test_chain_dynamics.py` checks the recursive solve
of `featherstar.fmu_src.chain` against it. The geometry, fluid terms and internal torques below are copied
from that commit, not imported, so that the reference does not move with the code it checks.

The drag follows the quadrature the model adopted in issue 26 (item 0), written here afresh: each
link's span and, at each of its two Gauss stations, each flap's chord is a line whose points move
with the plate; the normal speed at its ends comes from this file's own Jacobians, the line is cut
at its zero if the model splits, and numpy's Gauss–Legendre nodes are placed on each piece. The
model's own rule (`featherstar.fmu_src.drag_quadrature`) is not imported."""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from featherstar.fmu_src.contact import one_way_stop
from featherstar.fmu_src.feather import ADDED_MASS_CHORD, GAUSS
from featherstar.fmu_src.fluid import dnv_added_mass_coeff, oscillatory_drag_coeff, stroke_keulegan_carpenter
from featherstar.fmu_src.model import Model


def dense_feather_function(model: Model) -> ca.Function:
    """ode(x, u, p, qdd) -> (xdot, y, M, f, y_at) of `model` (a feather_model) in the dense
    formulation: the equations M(Q) Q̈ = f(Q, Q̇) it solves, and y_at, the outputs had the
    accelerations been the given `qdd` rather than the solution of those equations, and the size
    of the terms that cancel in the root torque, Σ_k |M_θk q̈_k| + |f_θ|."""
    morphology, n_units = model.options["morphology"], model.options["n_units"]
    supported = bool(model.options.get("root_support", False))
    p = ca.SX.sym("p", len(model.parameters))
    P = {par.name: p[i] for i, par in enumerate(model.parameters)}
    theta0, theta0_rate, theta0_accel, flow_speed = (ca.SX.sym(n) for n in ("th", "thd", "thdd", "U"))

    length, thick = P["length_m"], P["thickness_m"]
    rho, rho_s, grav = P["water_density_kg_m3"], P["solid_density_kg_m3"], P["gravity_m_s2"]
    if morphology == "chordwise":
        spine = P["spine_width_m"]
        width = P["width_ratio"] * spine
        chord = 0.5 * (width - spine)
        bending_width = spine + 2.0 * chord * P["flap_stiffness_share"]
        # Strips of width w_s and b have less added mass than one of width w; κ restores the flat
        # plate's ρπw²/4 (a heuristic, see physics spec §3).
        kappa = width**2 / (spine**2 + 2.0 * chord**2)
    else:
        width = P["width_m"]
        spine, chord, bending_width, kappa = width, None, width, 1.0
    flexural_rigidity = P["youngs_modulus_Pa"] * bending_width * thick**3 / 12.0
    short, long_ = ca.fmin(width, length), ca.fmax(width, length)
    added_mass_coeff = P["added_mass_scale"] * dnv_added_mass_coeff(long_ / short) * short**2 * long_ / (width**2 * length)

    def drag_coeff(span_m):
        """C_d at distance span_m from the root: oscillatory-flow plate value or the constant."""
        kc = stroke_keulegan_carpenter(span_m, P["stroke_amplitude_rad"], width)
        return ca.if_else(P["oscillatory_drag"] > 0.5, oscillatory_drag_coeff(kc), P["drag_coeff"])

    # Link lengths, joint kinds and bending stiffness (midpoint layout; see module docstring).
    if morphology == "spanwise":
        n_in = 0 if supported else n_units // 2  # bending units between the root and the hinge
        n_out = n_units - n_in
        root_length = length / P["length_ratio"]
        seg_out = (length - root_length) / n_out
        if supported:
            inner_links = [root_length]
        else:
            seg_in = root_length / n_in
            inner_links = [seg_in / 2] + [seg_in] * (n_in - 1) + [seg_in / 2]
        link_lengths = inner_links + [seg_out / 2] + [seg_out] * (n_out - 1) + [seg_out / 2]
        joints = ([] if supported else [("spring", flexural_rigidity / seg_in)] * n_in) + [("hinge", None)] + [
            ("spring", flexural_rigidity / seg_out)] * n_out
    else:
        seg = length / n_units
        link_lengths = [seg / 2] + [seg] * (n_units - 1) + [seg / 2]
        joints = [("spring", flexural_rigidity / seg)] * n_units
    n_joints = len(joints)
    n_flaps = len(link_lengths) if morphology == "chordwise" else 0
    q = ca.SX.sym("q", n_joints)
    psi = ca.SX.sym("psi", n_flaps)
    Q = ca.vertcat(q, psi)
    Q_rate = ca.SX.sym("qd", Q.numel())

    z_axis = ca.DM([0.0, 0.0, 1.0])
    points: list[Point] = []
    lines: list[tuple] = []  # (start, end, normal, area, C_d of the fraction t along the line)
    origin = ca.SX.zeros(3)
    arc = 0  # span coordinate of the link's start, from the root
    angle = theta0
    for j, link_length in enumerate(link_lengths):
        if j > 0:
            angle = angle + q[j - 1]
        along = ca.vertcat(ca.cos(angle), ca.sin(angle), 0)
        normal = ca.vertcat(-ca.sin(angle), ca.cos(angle), 0)
        for c in GAUSS:
            points.append(Point(
                origin + c * link_length * along, normal,
                rho_s * spine * thick * link_length / 2, added_mass_coeff * kappa * rho * math.pi * spine**2 / 4 * link_length / 2,
                0, spine * thick * link_length / 2, 0,
            ))
        spine_end = origin + link_length * along
        lines.append((origin, spine_end, normal, spine * link_length,
                      lambda t, arc=arc, dl=link_length: drag_coeff(arc + t * dl)))
        if morphology == "chordwise":
            fold = psi[j]
            flap_normal = ca.cos(fold) * normal + ca.sin(fold) * z_axis
            # Both flaps mirror each other in z: model one with doubled mass, area and added mass;
            # their z-forces cancel and their in-plane forces add.
            # The chord points sit where two points reproduce the strip's added mass and its first
            # and second moments about the hinge and carry the structural mass; the drag is on a
            # line across the chord at each Gauss station.
            for c in GAUSS:
                hinge_point = origin + c * link_length * along
                for s in ADDED_MASS_CHORD:
                    offset = (spine / 2 + s * chord * ca.cos(fold)) * z_axis - s * chord * ca.sin(fold) * normal
                    quarter = link_length * chord / 4
                    points.append(Point(
                        hinge_point + offset, flap_normal, 2 * rho_s * thick * quarter,
                        2 * added_mass_coeff * kappa * rho * math.pi * chord**2 / 4 * link_length / 4,
                        0, 2 * thick * quarter, 0,
                    ))
                hinge = hinge_point + spine / 2 * z_axis
                tip = hinge + chord * (ca.cos(fold) * z_axis - ca.sin(fold) * normal)
                lines.append((hinge, tip, flap_normal, link_length * chord,
                              lambda t, cd=drag_coeff(arc + c * link_length): cd))
        origin = origin + link_length * along
        arc = arc + link_length

    # Lagrange's equations over G = (Q, θ0) with θ0 prescribed: the rows of Q give Q̈, the row of
    # θ0 gives the torque the actuator must apply.
    y_axis = ca.DM([0.0, 1.0, 0.0])
    coords = ca.vertcat(Q, theta0)
    coord_rates = ca.vertcat(Q_rate, theta0_rate)
    n_free = Q.numel()
    gravity_force = (rho - rho_s) * grav * y_axis  # net buoyancy per unit volume
    dynamics = [point_dynamics(pt, coords, coord_rates, n_free, theta0_accel, flow_speed, rho, gravity_force)
                for pt in points]
    mass_matrix = sum(d.mass_matrix for d in dynamics)
    line_drag = [line_drag_force(*line, coords, coord_rates, flow_speed, rho, model.options["drag_points"],
                                 model.options["drag_split"]) for line in lines]
    generalized_force = sum(d.applied - d.bias for d in dynamics) + sum(g for g, _ in line_drag)

    internal, elastic_energy, fold_angle = _internal_torques(morphology, joints, q, psi, Q_rate, P, width, link_lengths)
    # Flaps first: their block of M is diagonal, so eliminating them first causes no fill-in.
    order = list(range(n_joints, n_free)) + list(range(n_joints))
    permuted = ldl_solve(mass_matrix[order, order], (generalized_force[:n_free] - internal)[order])
    solved = ca.vertcat(*[permuted[order.index(k)] for k in range(n_free)])
    Q_accel = ca.SX.sym("qdd", n_free)

    root_torque = ca.dot(mass_matrix[n_free, :n_free].T, Q_accel) - generalized_force[n_free]
    drag_thrust = sum(force[1] for _, force in line_drag)
    thrust = drag_thrust - sum(d.momentum_rate(Q_accel)[1] for d in dynamics)
    momentum_y = sum(d.momentum()[1] for d in dynamics)
    # ∂(momentum_y)/∂U: what the body's acceleration U̇ would add to the root force, −surge_mass·U̇.
    surge_mass = sum(pt.mass_kg + pt.added_mass_kg * pt.normal[1] ** 2 for pt in points)
    kinetic_energy = sum(d.kinetic_energy() for d in dynamics)
    # Buoyancy energy counted from the position of least potential a point can reach (no point is
    # farther than l + w from the root), so that the energy is never negative.
    reach = length + width
    buoyancy_energy = sum(pt.volume_m3 * (ca.fabs(gravity_force[1]) * reach - ca.dot(gravity_force, pt.position))
                          for pt in points)
    tip = origin

    outputs = ca.vertcat(thrust, root_torque, tip[0], tip[1], fold_angle,
                         kinetic_energy + elastic_energy + buoyancy_energy, drag_thrust, momentum_y, surge_mass)
    return ca.Function("dense", [ca.vertcat(Q, Q_rate), ca.vertcat(theta0, theta0_rate, theta0_accel, flow_speed), p,
                                 Q_accel],
                       [ca.vertcat(Q_rate, solved), ca.substitute(outputs, Q_accel, solved),
                        mass_matrix[:n_free, :n_free], generalized_force[:n_free] - internal, outputs,
                        ca.dot(ca.fabs(mass_matrix[n_free, :n_free].T), ca.fabs(Q_accel)) + ca.fabs(generalized_force[n_free])],
                       ["x", "u", "p", "qdd"], ["xdot", "y", "M", "f", "y_at", "root_torque_terms"])


def _internal_torques(morphology, joints, q, psi, Q_rate, P, width, link_lengths):
    """Generalised internal torques (springs, damping, hinge stops), elastic energy and the fold
    angle reported as an output."""
    n_joints = q.numel()
    torques = []
    energy = 0
    fold_angle = ca.SX(0)
    for k, (kind, stiffness) in enumerate(joints):
        rate = Q_rate[k]
        if kind == "spring":
            damping = P["retardation_time_s"] * stiffness + P["joint_damping_Nms_rad"]
            torques.append(stiffness * q[k] + damping * rate)
            energy += 0.5 * stiffness * q[k] ** 2
        else:
            # Folding is a negative relative angle: the outer part trails on the upstroke.
            torque, hinge_energy = _hinge(-q[k], -rate, P, width)
            torques.append(-torque)
            energy += hinge_energy
            fold_angle = -q[k]
    for k in range(psi.numel()):
        hinge_length = 2 * link_lengths[k]  # two flaps, each hinged along the link
        torque, hinge_energy = _hinge(psi[k], Q_rate[n_joints + k], P, hinge_length)
        torques.append(torque)
        energy += hinge_energy
    if psi.numel():
        fold_angle = ca.sum1(psi) / psi.numel()
    return ca.vertcat(*torques), energy, fold_angle


def _hinge(fold, fold_rate, P, hinge_length):
    """Torque resisting `fold` (positive = folding) and its elastic energy: a weak hinge spring,
    a stop at 0 (flat) and a stop at the fold limit, both one-way penalties exactly zero before
    contact."""
    k_c = P["contact_stiffness_Nm_rad_m"] * hinge_length
    c_c = P["contact_damping_Nms_rad_m"] * hinge_length
    eps = P["contact_smoothing_rad"]
    flat_torque, flat_energy = one_way_stop(-fold, -fold_rate, k_c, c_c, eps)
    limit_torque, limit_energy = one_way_stop(fold - P["fold_limit_rad"], fold_rate, k_c, c_c, eps)
    k_h = P["hinge_stiffness_Nm_rad_m"] * hinge_length
    torque = k_h * fold - flat_torque + limit_torque
    return torque, 0.5 * k_h * fold**2 + flat_energy + limit_energy


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


def line_drag_force(start, end, normal, area, drag_coeff_at, coords, coord_rates, flow_speed, water_density,
                    points: int, split: bool) -> tuple[ca.SX, ca.SX]:
    """(generalized force, force vector) of the quadratic drag on a straight line of a rigid plate
    from `start` to `end` (root-frame expressions): −½ρ C_d area ∫₀¹ |v_n| v_n dt n. A point at
    the fraction t has Jacobian (1 − t) J_start + t J_end, t held fixed."""
    jac_start, jac_end = ca.jacobian(start, coords), ca.jacobian(end, coords)
    flow = flow_speed * ca.DM([0.0, 1.0, 0.0])

    def jacobian_at(t):
        return (1 - t) * jac_start + t * jac_end

    def speed_at(t):
        return ca.dot(normal, jacobian_at(t) @ coord_rates + flow)

    nodes, weights = np.polynomial.legendre.leggauss(points)
    unit = [((1 + x) / 2, w / 2) for x, w in zip(nodes, weights)]
    if split:
        s0, s1 = speed_at(0), speed_at(1)
        zero = ca.if_else(s0 * s1 < 0, s0 / ca.if_else(s0 * s1 < 0, s0 - s1, 1), 1)
        pieces = [(zero * t, zero * w) for t, w in unit] + [(zero + (1 - zero) * t, (1 - zero) * w) for t, w in unit]
    else:
        pieces = unit
    generalized, force = 0, 0
    for t, w in pieces:
        speed = speed_at(t)
        drag = -0.5 * water_density * drag_coeff_at(t) * area * w * ca.fabs(speed) * speed * normal
        generalized = generalized + jacobian_at(t).T @ drag
        force = force + drag
    return generalized, force


def _is_zero(expr: ca.SX) -> bool:
    return expr.is_zero() if isinstance(expr, ca.SX) else expr == 0


def ldl_solve(matrix: ca.SX, rhs: ca.SX) -> ca.SX:
    """x with matrix·x = rhs, for a symmetric positive definite `matrix` (no pivoting)."""
    n = matrix.size1()
    lower = [[ca.SX(0)] * n for _ in range(n)]
    diag = [ca.SX(0)] * n
    for i in range(n):
        for j in range(i):
            value = matrix[i, j]
            for k in range(j):
                if not (_is_zero(lower[i][k]) or _is_zero(lower[j][k])):
                    value = value - lower[i][k] * lower[j][k] * diag[k]
            lower[i][j] = ca.SX(0) if _is_zero(value) else value / diag[j]
        value = matrix[i, i]
        for k in range(i):
            if not _is_zero(lower[i][k]):
                value = value - lower[i][k] ** 2 * diag[k]
        diag[i] = value
    forward = [ca.SX(0)] * n
    for i in range(n):
        value = rhs[i]
        for k in range(i):
            if not _is_zero(lower[i][k]):
                value = value - lower[i][k] * forward[k]
        forward[i] = value
    solution = [ca.SX(0)] * n
    for i in reversed(range(n)):
        value = forward[i] / diag[i]
        for k in range(i + 1, n):
            if not _is_zero(lower[k][i]):
                value = value - lower[k][i] * solution[k]
        solution[i] = value
    return ca.vertcat(*solution)
