"""The feather's equations of motion solved along its chain in O(N) (articulated-body recursion).

The feather is a tree of rigid plates: a planar chain of links (each turning about z relative to
the one before it, the first driven by the prescribed root angle θ0) and, on chordwise feathers,
one flap per link folding about the link's axis. Every quadrature point lies on its plate's
mid-surface and its added mass acts along the plate's normal.

The equations are Lagrange's, as `featherstar.fmu_src.fluid` derives them: for every coordinate k,

    Σ_p [∂r_p/∂G_k · F_p − ∂Ω_p/∂Ġ_k · C_p] = −τ_k,
    F_p = (m_p I + m_a,p n nᵀ) a_p + m_a,p [(ṅ·w) n + v_n ṅ] − F_drag,p − V_p g_net ŷ,
    C_p = m_a,p v_n (n × w)  (the Munk couple),

with τ_k the internal (spring, damper, stop) torque of coordinate k. The mass matrix is never
formed: each link's subtree is summarised, from the tip inwards, by its articulated inertia and
bias wrench about the link's origin (Featherstone, Rigid Body Dynamics Algorithms, 2008, ch. 7),
in the link's own frame, where the planar part of each plate's inertia is a constant. A flap is a
leaf with one degree of freedom and is eliminated into its link first. Accelerations then follow
from the root outwards. Planar quantities are (α_z, a_along, a_normal) for motions and
(moment_z, force_along, force_normal) for wrenches, each about the link's origin in its frame.
Cost per link is fixed, so one evaluation grows as N (the symbolic LDLᵀ of the dense mass matrix
this replaces grew as N³).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import casadi as ca

from .drag_quadrature import DragRule
from .fluid import fluid_loads
from .strip_drag import DragStrip, StripDrag, WakeLaw, strip_drag


@dataclass(frozen=True)
class PlatePoint:
    """A mass quadrature point of a plate, in the plate's frame. `along_m` is measured from the
    link's start along the link; `across_m` from the flap's hinge along the flap (0 for spine
    points). Drag is carried by `DragStrip`s, which have their own quadrature."""

    along_m: ca.SX
    across_m: ca.SX
    mass_kg: ca.SX
    added_mass_kg: ca.SX
    volume_m3: ca.SX


@dataclass(frozen=True)
class Link:
    """One rigid link of the chain and, if `flap` is not empty, the flap hinged along it at
    `hinge_offset_m` from the link's axis (out of the plane, +z); each plate's drag strips."""

    length_m: ca.SX
    spine: tuple[PlatePoint, ...]
    spine_drag: tuple[DragStrip, ...]
    flap: tuple[PlatePoint, ...] = ()
    flap_drag: tuple[DragStrip, ...] = ()
    hinge_offset_m: ca.SX = 0.0


@dataclass(frozen=True)
class ChainMotion:
    """The chain's state and drive: θ0 and its rates, body speed U along +y, the joint angles q
    (one fewer than links) and fold angles ψ (one per flapped link), their rates, and the internal
    torques resisting each (same order)."""

    root_angle: ca.SX
    root_rate: ca.SX
    root_accel: ca.SX
    flow_speed_m_s: ca.SX
    joint_angles: ca.SX
    joint_rates: ca.SX
    joint_torques: ca.SX
    fold_angles: ca.SX
    fold_rates: ca.SX
    fold_torques: ca.SX


@dataclass(frozen=True)
class ChainSolution:
    """Accelerations and what the load cell and the energy audit read (root frame)."""

    joint_accels: ca.SX
    fold_accels: ca.SX
    root_torque_Nm: ca.SX
    thrust_N: ca.SX
    drag_thrust_N: ca.SX
    momentum_y_Ns: ca.SX
    surge_mass_kg: ca.SX
    kinetic_energy_J: ca.SX
    volume_m3: ca.SX
    volume_height_m4: ca.SX  # Σ_p V_p y_p: the buoyancy's potential is −(ρ − ρ_s) g times this
    tip_m: tuple[ca.SX, ca.SX]
    wake_rates: ca.SX  # u̇ of every strip's wake states, in the order of the links' strips
    wake_energy_J: ca.SX  # Σ ½ m_w u²: the wake's kinetic energy
    dissipation_W: ca.SX  # the drag's power lost in the water: relative motion plus the wake's decay


def _vec(*components: ca.SX) -> ca.SX:
    return ca.vertcat(*components)


class _Sums:
    """Root-frame outputs summed over every point of the chain."""

    def __init__(self) -> None:
        self.drag_y = self.momentum_y = self.surge_mass = self.kinetic = ca.SX(0)
        self.volume = self.volume_height = ca.SX(0)
        self.wake_energy = self.dissipation = ca.SX(0)
        self.wake_rates: list[ca.SX] = []

    def add(self, drag: StripDrag) -> None:
        self.drag_y += drag.drag_y_N
        self.wake_rates += drag.wake_rates
        self.wake_energy += drag.wake_energy_J
        self.dissipation += drag.dissipation_W


def solve_chain(
    links: Sequence[Link], motion: ChainMotion, net_buoyancy_N_m3: ca.SX, drag_rule: DragRule,
    wake: WakeLaw | None = None,
) -> ChainSolution:
    """Accelerations of every joint and fold and the load-cell outputs, in O(len(links)).

    `net_buoyancy_N_m3` is (ρ − ρ_s) g: the net upward (+y) force per unit volume; `drag_rule`
    integrates the drag along each strip; `wake` (strips with a StripWake) gives their wakes' rates."""
    n_links = len(links)
    flapped = [j for j, link in enumerate(links) if link.flap]
    if motion.joint_angles.numel() != n_links - 1 or motion.fold_angles.numel() != len(flapped):
        raise ValueError("solve_chain: joint/fold coordinates do not match the links")
    sums = _Sums()
    fold_index = {j: k for k, j in enumerate(flapped)}

    # Outward: kinematics, each link's inertia (constant in its frame but for the fold) and the
    # wrench its points need when every acceleration of the tree is zero.
    cos_abs, sin_abs = ca.cos(motion.root_angle), ca.sin(motion.root_angle)
    rate = motion.root_rate
    vel_along, vel_normal = ca.SX(0), ca.SX(0)  # the link origin's velocity, link frame
    origin_x, origin_y = ca.SX(0), ca.SX(0)  # the link origin, root frame
    inertias, biases, joints, flap_terms = [], [], [], {}
    for j, link in enumerate(links):
        if j > 0:
            prev = links[j - 1].length_m
            cq, sq = ca.cos(motion.joint_angles[j - 1]), ca.sin(motion.joint_angles[j - 1])
            # The parent's end moves at (v_a, v_n + ω L) in the parent's frame; rotate by q.
            va, vn = vel_along, vel_normal + rate * prev
            vel_along, vel_normal = cq * va + sq * vn, -sq * va + cq * vn
            origin_x, origin_y = origin_x + prev * cos_abs, origin_y + prev * sin_abs
            joints.append((cq, sq, prev, rate**2 * prev))
            cos_abs, sin_abs = cos_abs * cq - sin_abs * sq, sin_abs * cq + cos_abs * sq
            rate = rate + motion.joint_rates[j - 1]
        frame = _Frame(cos_abs, sin_abs, origin_y, _vec(sin_abs, cos_abs, 0), motion.flow_speed_m_s,
                       net_buoyancy_N_m3)
        spin = _vec(0, 0, rate)
        bias = ca.SX.zeros(3)
        for pt in link.spine:
            offset = _vec(pt.along_m, 0, 0)
            velocity = _vec(vel_along, vel_normal + rate * pt.along_m, 0)
            bias_accel = ca.cross(spin, ca.cross(spin, offset))
            wrench, _ = _point_wrench(pt, offset, _vec(0, 1, 0), spin, velocity, bias_accel, frame, sums)
            bias = bias + wrench

        def spine_kinematics(along, across):
            return _vec(along, 0, 0), _vec(vel_along, vel_normal + rate * along, 0)

        for strip in link.spine_drag:
            drag = strip_drag(strip, drag_rule, wake, _vec(0, 1, 0), spine_kinematics, frame.flow_speed_m_s * frame.up,
                              frame.up)
            sums.add(drag)
            bias = bias + drag.wrench
        inertia = _spine_inertia(link.spine)
        if link.flap:
            k = fold_index[j]
            cf, sf = ca.cos(motion.fold_angles[k]), ca.sin(motion.fold_angles[k])
            fold_rate = motion.fold_rates[k]
            normal = _vec(0, cf, sf)
            flap_spin = _vec(fold_rate, 0, rate)
            fold_free = motion.fold_torques[k]
            for pt in link.flap:
                from_hinge = _vec(pt.along_m, -pt.across_m * sf, pt.across_m * cf)
                offset = from_hinge + _vec(0, 0, link.hinge_offset_m)
                velocity = _vec(vel_along, vel_normal, 0) + ca.cross(flap_spin, from_hinge)
                # Ω̇ has ψ̇ω n beside the accelerations; the rest is centripetal.
                bias_accel = (ca.cross(_vec(0, fold_rate * rate, 0), from_hinge)
                              + ca.cross(flap_spin, ca.cross(flap_spin, from_hinge)))
                wrench, fold_moment = _point_wrench(pt, offset, normal, flap_spin, velocity, bias_accel, frame, sums)
                bias = bias + wrench
                fold_free = fold_free + fold_moment

            def flap_kinematics(along, across, cf=cf, sf=sf, flap_spin=flap_spin, h=link.hinge_offset_m):
                from_hinge = _vec(along, -across * sf, across * cf)
                return (from_hinge + _vec(0, 0, h),
                        _vec(vel_along, vel_normal, 0) + ca.cross(flap_spin, from_hinge))

            for strip in link.flap_drag:
                drag = strip_drag(strip, drag_rule, wake, normal, flap_kinematics, frame.flow_speed_m_s * frame.up,
                                  frame.up)
                sums.add(drag)
                bias = bias + drag.wrench
                fold_free = fold_free + drag.fold_moment
            flap_inertia, fold_inertia, coupling = _flap_inertia(link.flap, cf, sf)
            flap_terms[j] = (fold_inertia, coupling, fold_free)
            # The fold equation d ψ̈ + couplingᵀA + fold_free = 0 eliminates ψ̈ into the link.
            inertia = inertia + flap_inertia - coupling @ coupling.T / fold_inertia
            bias = bias - coupling * (fold_free / fold_inertia)
        inertias.append(inertia)
        biases.append(bias)
    tip = (origin_x + links[-1].length_m * cos_abs, origin_y + links[-1].length_m * sin_abs)

    # Inward: each subtree's articulated inertia and bias wrench about its link's origin. A child's
    # origin acceleration in its own frame is X·A_parent + offset_accel + (q̈, 0, 0).
    art_inertia, art_bias = list(inertias), list(biases)
    transforms: list[tuple[ca.SX, ca.SX]] = []
    for cq, sq, length, centripetal in joints:
        X = ca.SX(3, 3)
        X[0, 0] = 1
        X[1, 0], X[1, 1], X[1, 2] = sq * length, cq, sq
        X[2, 0], X[2, 1], X[2, 2] = cq * length, -sq, cq
        transforms.append((X, _vec(0, -cq * centripetal, sq * centripetal)))
    for k in range(n_links - 1, 0, -1):
        X, offset_accel = transforms[k - 1]
        ia, pa = art_inertia[k], art_bias[k]
        column = ia[:, 0]
        free = pa[0] + motion.joint_torques[k - 1]
        reduced = ia - column @ column.T / ia[0, 0]
        passed = pa + reduced @ offset_accel - column * (free / ia[0, 0])
        art_inertia[k - 1] = art_inertia[k - 1] + X.T @ reduced @ X
        art_bias[k - 1] = art_bias[k - 1] + X.T @ passed

    # Outward: accelerations. The root link turns about the fixed root.
    accel = _vec(motion.root_accel, 0, 0)
    root_wrench = art_inertia[0] @ accel + art_bias[0]
    joint_accels, fold_accels = [], []
    for j in range(n_links):
        if j > 0:
            X, offset_accel = transforms[j - 1]
            accel = X @ accel + offset_accel
            ia = art_inertia[j]
            qdd = -(art_bias[j][0] + motion.joint_torques[j - 1] + ca.dot(ia[:, 0], accel)) / ia[0, 0]
            joint_accels.append(qdd)
            accel = accel + _vec(qdd, 0, 0)
        if j in flap_terms:
            fold_inertia, coupling, fold_free = flap_terms[j]
            fold_accels.append(-(fold_free + ca.dot(coupling, accel)) / fold_inertia)

    # Σ_p F_p is the force the root exerts on the feather; less the drag and the (tared) static
    # buoyancy it is −Σ_p d/dt(momentum + fluid impulse)_p, which the load cell adds to the drag.
    force_y = ca.sin(motion.root_angle) * root_wrench[1] + ca.cos(motion.root_angle) * root_wrench[2]
    return ChainSolution(
        joint_accels=ca.vertcat(*joint_accels),
        fold_accels=ca.vertcat(*fold_accels),
        root_torque_Nm=root_wrench[0],
        thrust_N=-force_y - net_buoyancy_N_m3 * sums.volume,
        drag_thrust_N=sums.drag_y,
        momentum_y_Ns=sums.momentum_y,
        surge_mass_kg=sums.surge_mass,
        kinetic_energy_J=sums.kinetic,
        volume_m3=sums.volume,
        volume_height_m4=sums.volume_height,
        tip_m=tip,
        wake_rates=ca.vertcat(*sums.wake_rates),
        wake_energy_J=sums.wake_energy,
        dissipation_W=sums.dissipation,
    )


@dataclass(frozen=True)
class _Frame:
    """A link's orientation and origin height (root frame), with ŷ, the body speed and the net
    buoyancy per volume it needs to load its points."""

    cos_abs: ca.SX
    sin_abs: ca.SX
    origin_y: ca.SX
    up: ca.SX
    flow_speed_m_s: ca.SX
    net_buoyancy_N_m3: ca.SX


def _point_wrench(pt: PlatePoint, offset: ca.SX, normal: ca.SX, spin: ca.SX, velocity: ca.SX, bias_accel: ca.SX,
                  frame: _Frame, sums: _Sums) -> tuple[ca.SX, ca.SX]:
    """The planar wrench about the link origin of point `pt` (at `offset`, link frame) with all
    accelerations of the tree zero, and its moment about a flap hinge (∂r/∂ψ = −across·n,
    ∂Ω/∂ψ̇ = the link axis). Adds the point's outputs to `sums`."""
    relative = velocity + frame.flow_speed_m_s * frame.up
    loads = fluid_loads(pt.added_mass_kg, normal, ca.cross(spin, normal), relative)
    m, m_a = pt.mass_kg, pt.added_mass_kg
    force = (m * bias_accel + m_a * ca.dot(normal, bias_accel) * normal + loads.impulse_rate_N
             - pt.volume_m3 * frame.net_buoyancy_N_m3 * frame.up)
    couple = -loads.munk_couple_Nm
    wrench = _vec(offset[0] * force[1] - offset[1] * force[0] + couple[2], force[0], force[1])
    fold_moment = -pt.across_m * ca.dot(normal, force) + couple[0]
    normal_up = ca.dot(normal, frame.up)
    sums.momentum_y += m * ca.dot(velocity, frame.up) + m_a * loads.normal_speed_m_s * normal_up
    sums.surge_mass += m + m_a * normal_up**2
    sums.kinetic += 0.5 * m * ca.dot(velocity, velocity) + 0.5 * m_a * ca.dot(normal, velocity) ** 2
    sums.volume += pt.volume_m3
    sums.volume_height += pt.volume_m3 * (frame.origin_y + frame.sin_abs * offset[0] + frame.cos_abs * offset[1])
    return wrench, fold_moment


def _spine_inertia(points: Sequence[PlatePoint]) -> ca.SX:
    """Planar inertia of the link's own points about its origin (link frame): Σ_p Jᵀ(m I + m_a n nᵀ)J
    with J = [ẑ×ρ | e_along | e_normal], ρ = (x, 0, 0), n = e_normal."""
    mass = sum(pt.mass_kg for pt in points)
    total = [pt.mass_kg + pt.added_mass_kg for pt in points]
    first = sum(t * pt.along_m for t, pt in zip(total, points))
    second = sum(t * pt.along_m**2 for t, pt in zip(total, points))
    return ca.blockcat([[second, 0, first], [0, mass, 0], [first, 0, sum(total)]])


def _flap_inertia(points: Sequence[PlatePoint], cf: ca.SX, sf: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """The flap at fold ψ (cf = cos ψ, sf = sin ψ): its planar inertia about the link's origin, its
    inertia about the hinge, and the coupling Σ_p Jᵀ M_p ∂r_p/∂ψ of fold and link accelerations.
    A point at (x, across c) has ρ = (x, −c sψ, h + c cψ), n = (0, cψ, sψ), ∂r/∂ψ = −c n."""
    m = [pt.mass_kg for pt in points]
    m_a = [pt.added_mass_kg for pt in points]
    x = [pt.along_m for pt in points]
    c = [pt.across_m for pt in points]
    mass, added = sum(m), sum(m_a)
    zz = sum(mi * ci**2 for mi, ci in zip(m, c))
    inertia = ca.blockcat([
        [sum(mi * xi**2 for mi, xi in zip(m, x)) + sf**2 * zz + cf**2 * sum(ai * xi**2 for ai, xi in zip(m_a, x)),
         sf * sum(mi * ci for mi, ci in zip(m, c)),
         sum(mi * xi for mi, xi in zip(m, x)) + cf**2 * sum(ai * xi for ai, xi in zip(m_a, x))],
        [0, mass, 0],
        [0, 0, mass + cf**2 * added],
    ])
    inertia = ca.triu(inertia) + ca.triu(inertia, False).T
    fold = sum((mi + ai) * ci**2 for mi, ai, ci in zip(m, m_a, c))
    lever = [(mi + ai) * ci for mi, ai, ci in zip(m, m_a, c)]
    coupling = -cf * _vec(sum(li * xi for li, xi in zip(lever, x)), 0, sum(lever))
    return inertia, fold, coupling
