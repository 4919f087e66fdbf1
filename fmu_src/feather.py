"""Lumped-parameter feather flapped at its root in water (plain, chordwise flaps, spanwise flaps).

The feather is a chain of rigid links joined by rotational springs (Stella et al. 2022, as read in
docs/model.md): springs sit at the midpoints of N equal segments, so the first half-segment is
rigid with the actuator and the tip link is half length (f1, f2 within 1 % of Euler–Bernoulli at
N = 10). Each link carries quadrature points; each point has structural mass, added mass along its
surface normal, a normal-drag area, a drag coefficient and a net-buoyancy volume. Chordwise flaps
add a fold angle per link whose flap points move out of the plane (z); spanwise flaps put a
one-way hinge at l_root, the part inside it held rigid by the support. The generalised
coordinates Q are the joint and fold angles; the equations are Lagrange's,

    M(Q) Q̈ = Σ_p [J_pᵀ F_p − b_p] − τ_internal,   M = Σ_p J_pᵀ (m_p I + m_a,p n_p n_pᵀ) J_p,

where b_p holds the inertial and fluid-reactive terms not proportional to Q̈ (`featherstar.fmu_src.fluid`:
the fluid force follows from the fluid's kinetic energy ½ Σ m_a v_n², so it conserves energy and
its mean over a periodic motion is zero), solved along the chain in O(N) without forming M
(`featherstar.fmu_src.chain`). Added mass sits on the inertia side because it is 100–160× the structural
mass: applied explicitly from a lagged acceleration it is unstable.
The load cell reads ŷ·Σ_p (F_drag,p − d/dt(m_p v_p + m_a,p v_n,p n_p)): the momentum balance of
structure plus fluid impulse; the static buoyancy is tared away exactly.
"""
from __future__ import annotations

import math

import casadi as ca

from .errors import ModelError
from .model import Model, Parameter, Variable
from .contact import one_way_stop
from .chain import ChainMotion, Link, PlatePoint, solve_chain
from .drag_quadrature import DragRule
from .strip_drag import DragStrip, StripWake, WakeLaw
from .fluid import WAKE_CONSTANTS, WAKE_LAWS, dnv_added_mass_coeff, oscillatory_drag_coeff, stroke_keulegan_carpenter

MORPHOLOGIES = ("plain", "chordwise", "spanwise")
GAUSS = (0.5 - 0.5 / math.sqrt(3.0), 0.5 + 0.5 / math.sqrt(3.0))
# Two points at these chord fractions reproduce a strip's added mass and its first and second
# moments about the hinge (m' = ρπb²/4, S' = m'b/2, J' = 9ρπb⁴/128).
ADDED_MASS_CHORD = (0.5 - 1.0 / math.sqrt(32.0), 0.5 + 1.0 / math.sqrt(32.0))
#: The drag quadrature by default: 4 Gauss points on each strip, the rule with the fewest points
#: whose test-bed TR and mean thrust are within 0.1 % of the finest rule's for every morphology
#: (bench/drag_convergence.py, docs/results/drag_convergence.json; the spanwise feather's long
#: supported root link, over which C_d(KC) has its kink, is what needs the 4: the split rule, exact
#: for |s| s, needs as many there).
DEFAULT_DRAG_POINTS, DEFAULT_DRAG_SPLIT = 4, False


#: The sheet's material damping as a Kelvin-Voigt solid, sigma = E (eps + tau d(eps)/dt): a mode at
#: frequency f is damped with ratio zeta = pi f tau. Polypropylene's loss factor near room
#: temperature is eta ~ 0.05-0.1 from 1 to 100 Hz; tau = eta / (2 pi f_ref) with eta = 0.05 and
#: f_ref = 50 Hz, above what the stroke excites (ramps >= 0.1 s), so every mode the stroke drives is
#: damped no more than the real sheet (zeta <= eta / 2), while the lumped chain's highest modes
#: (tens of kHz for short links: artifacts of the discretization, with no damping they ring for
#: ever and set the integrator's step, bench/feather_speed.py section 5) are damped as a material
#: damps them.
RETARDATION_TIME_S = 0.05 / (2 * math.pi * 50.0)


def _common_parameters() -> list[Parameter]:
    return [
        Parameter("length_m", 0.115, "m", 0.0, 1.0, "feather length l (paper: 11.5 cm)", True),
        Parameter("thickness_m", 0.4e-3, "m", 0.0, 0.01, "sheet thickness (0.4 mm PP)", True),
        Parameter("youngs_modulus_Pa", 1.5e9, "Pa", 0.0, 1e12, "Young's modulus (PP: 1.24–1.8 GPa)", True),
        Parameter("solid_density_kg_m3", 905.0, "kg/m3", 0.0, 20000.0, "sheet density (PP 905)", True),
        Parameter("water_density_kg_m3", 1000.0, "kg/m3", 0.0, 2000.0, "fluid density", True),
        Parameter("gravity_m_s2", 9.81, "m/s2", 0.0, 20.0, "gravity along -y (the thrust axis)"),
        Parameter("oscillatory_drag", 1.0, "1", 0.0, 1.0,
                  "1: each point's C_d from its Keulegan-Carpenter number (Luhar & Nepf 2016); 0: the constant drag_coeff",
                  choices=(0.0, 1.0)),
        Parameter("stroke_amplitude_rad", math.radians(60.0), "rad", 0.0, math.pi,
                  "peak-to-peak root stroke that sets each point's KC = pi*s*A/w (oscillatory drag)", True),
        Parameter("drag_coeff", 1.2, "1", 0.0, 10.0, "constant normal drag coefficient C_n when oscillatory_drag = 0 (steady plate 1.2)"),
        Parameter("added_mass_scale", 1.0, "1", 0.0, 3.0, "multiplier on the DNV 3D added-mass coefficient"),
        Parameter("retardation_time_s", RETARDATION_TIME_S, "s", 0.0, 1.0,
                  "Kelvin-Voigt retardation time of the sheet: each bending joint's damping is this times its "
                  "stiffness (PP loss factor 0.05 matched at 50 Hz, see RETARDATION_TIME_S)"),
        Parameter("joint_damping_Nms_rad", 0.0, "N.m.s/rad", 0.0, 1.0,
                  "viscous damping of each bending joint added to the material's (retardation_time_s)"),
    ]


#: Parameters of the quasi-steady drag law that a wake replaces (its C_0 is constant: the wake
#: itself makes an oscillating plate's drag depend on KC, so C_d(KC) is not counted twice).
QUASI_STEADY_DRAG = ("oscillatory_drag", "stroke_amplitude_rad", "drag_coeff")


def _wake_parameters(law: str) -> list[Parameter]:
    drag_coeff_0, forcing, decay_widths = WAKE_CONSTANTS[law]
    return [
        Parameter("wake_drag_coeff", drag_coeff_0, "1", 0.0, 20.0,
                  f"C_0 of the drag on the speed relative to the wake ('{law}' law fitted to oscillatory and steady plate data)"),
        Parameter("wake_forcing", forcing, "1", 0.0, 10.0, "B: how fast the drag sets the dragged water moving"),
        Parameter("wake_decay_widths", decay_widths, "1", 0.0, 1000.0,
                  "gamma: the wake's decay length in feather widths", True),
    ]


def _hinge_parameters(fold_limit_deg: float) -> list[Parameter]:
    return [
        Parameter("hinge_stiffness_Nm_rad_m", 1e-2, "N.m/rad/m", 0.0, 1.0,
                  "spring of the tape hinge per metre of hinge (tape estimate 1e-3 to 1e-1)"),
        Parameter("contact_stiffness_Nm_rad_m", 10.0, "N.m/rad/m", 0.0, 1e5, "stop stiffness per metre of hinge", True),
        Parameter("contact_damping_Nms_rad_m", 0.08, "N.m.s/rad/m", 0.0, 100.0, "stop damping per metre of hinge"),
        Parameter("contact_smoothing_rad", math.radians(0.5), "rad", 0.0, 0.2, "penetration over which the stop force ramps in", True),
        Parameter("fold_limit_rad", math.radians(fold_limit_deg), "rad", 0.0, math.pi, "largest fold angle (second stop)", True),
    ]


def _morphology_parameters(morphology: str) -> list[Parameter]:
    if morphology == "plain":
        return [Parameter("width_m", 0.075, "m", 0.0, 1.0, "feather width w", True)]
    if morphology == "chordwise":
        return [
            Parameter("width_ratio", 7.5, "1", 1.0, 50.0, "WR = w / w_spine (flaps on both sides of the spine)", True),
            Parameter("spine_width_m", 0.01, "m", 0.0, 0.2, "spine width (paper: 1 cm)", True),
            Parameter("flap_stiffness_share", 1.0, "1", 0.0, 1.0, "share of the flaps' own bending stiffness that adds to the span's"),
            *_hinge_parameters(90.0),
        ]
    return [
        Parameter("width_m", 0.075, "m", 0.0, 1.0, "feather width w", True),
        Parameter("length_ratio", 2.0, "1", 1.0, 20.0, "LR = l / l_root (hinge at l_root)", True),
        *_hinge_parameters(160.0),
    ]


def feather_model(morphology: str = "plain", n_units: int = 10, root_support: bool | None = None,
                  drag_points: int = DEFAULT_DRAG_POINTS, drag_split: bool = DEFAULT_DRAG_SPLIT,
                  wake: str = "none") -> Model:
    """Build the feather model. `morphology`, `n_units`, `root_support` and the drag quadrature
    change the equations' structure and are therefore build options; every physical constant is a
    parameter.

    `drag_points`, `drag_split`: the quadrature of the quadratic drag along each link's span and
    across each flap's chord (`featherstar.fmu_src.drag_quadrature`): that many Gauss points, on
    each side of the zero of the normal speed with `drag_split`.

    `wake`: "none" (quasi-steady drag with C_d(KC)) or a law of `featherstar.fmu_src.fluid.WAKE_LAWS`:
    one wake state per mass point of every plate, the normal speed of the water it drags along,
    and drag on the speed relative to it with the law's constant C_0 (docs/model.md).

    `root_support` (spanwise only, default True): the part between the root and the hinge at
    l_root is held by the support (the paper, Sec. II-A: the spanwise feathers "have a joint at a
    distance l_root from the root where the support is") and moves as one rigid link; the outer
    part is a chain of `n_units` units. False: both parts bend, n_units/2 units each."""
    if morphology not in MORPHOLOGIES:
        raise ModelError(f"feather morphology '{morphology}' is unknown; valid: {', '.join(MORPHOLOGIES)}")
    if not isinstance(n_units, int) or not 2 <= n_units <= 60:
        raise ModelError(f"feather n_units = {n_units!r} must be an integer in [2, 60]")
    if root_support is not None and morphology != "spanwise":
        raise ModelError(f"feather root_support applies to the spanwise morphology only, not '{morphology}'")
    if root_support is not None and not isinstance(root_support, bool):
        raise ModelError(f"feather root_support = {root_support!r} must be true or false")
    if not isinstance(drag_points, int) or isinstance(drag_points, bool) or not 1 <= drag_points <= 64:
        raise ModelError(f"feather drag_points = {drag_points!r} must be an integer in [1, 64]")
    if not isinstance(drag_split, bool):
        raise ModelError(f"feather drag_split = {drag_split!r} must be true or false")
    if wake != "none" and wake not in WAKE_LAWS:
        raise ModelError(f"feather wake = {wake!r} is unknown; valid: none, {', '.join(WAKE_LAWS)}")
    supported = morphology == "spanwise" and root_support is not False

    parameters = _common_parameters() + _morphology_parameters(morphology)
    if wake != "none":
        parameters = [par for par in parameters if par.name not in QUASI_STEADY_DRAG] + _wake_parameters(wake)
    p = ca.SX.sym("p", len(parameters))
    P = {par.name: p[i] for i, par in enumerate(parameters)}
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
        """C_d at distance span_m from the root: oscillatory-flow plate value or the constant; with
        a wake, the law's C_0."""
        if wake != "none":
            return P["wake_drag_coeff"]
        kc = stroke_keulegan_carpenter(span_m, P["stroke_amplitude_rad"], width)
        return ca.if_else(P["oscillatory_drag"] > 0.5, oscillatory_drag_coeff(kc), P["drag_coeff"])

    wake_states: list[Variable] = []
    wake_symbols: list[ca.SX] = []

    def strip_wake(at: tuple[float, float], plate: str) -> StripWake | None:
        """Two new wake states at the fractions `at` of a strip (its mass points), or None."""
        if wake == "none":
            return None
        pair = []
        for t in at:
            k = len(wake_symbols)
            wake_symbols.append(ca.SX.sym(f"u{k}"))
            wake_states.append(Variable(f"wake_{k}_m_s", "m/s",
                                        f"normal speed of the water dragged along by {plate} (point {k})"))
            pair.append(wake_symbols[-1])
        return StripWake(at, tuple(pair))

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

    links: list[Link] = []
    arc = 0  # span coordinate of the link's start, from the root
    for link_length in link_lengths:
        spine_points = tuple(PlatePoint(
            c * link_length, 0, rho_s * spine * thick * link_length / 2,
            added_mass_coeff * kappa * rho * math.pi * spine**2 / 4 * link_length / 2, spine * thick * link_length / 2,
        ) for c in GAUSS)
        # The spine's drag along the whole link: the normal speed is affine along it.
        spine_drag = (DragStrip((0, 0), (link_length, 0),
                                lambda along, arc=arc, a=spine * link_length: 0.5 * rho * drag_coeff(arc + along) * a,
                                strip_wake(GAUSS, f"link {len(links)}'s spine")),)
        flap_points: tuple[PlatePoint, ...] = ()
        flap_drag: tuple[DragStrip, ...] = ()
        if morphology == "chordwise":
            # Both flaps mirror each other in z: model one with doubled mass, area and added mass;
            # their z-forces cancel and their in-plane forces add. The chord points sit where two
            # points reproduce the strip's added mass and its first and second moments about the
            # hinge; they also carry the structural mass. The drag is a line across the chord at
            # each of the link's Gauss points (the normal speed is affine across it).
            quarter = link_length * chord / 4
            flap_points = tuple(PlatePoint(
                c * link_length, s * chord, 2 * rho_s * thick * quarter,
                2 * added_mass_coeff * kappa * rho * math.pi * chord**2 / 4 * link_length / 4, 2 * thick * quarter,
            ) for c in GAUSS for s in ADDED_MASS_CHORD)
            flap_drag = tuple(DragStrip(
                (c * link_length, 0), (c * link_length, chord),
                lambda along, arc=arc, a=2 * quarter * 2: 0.5 * rho * drag_coeff(arc + along) * a,
                strip_wake(ADDED_MASS_CHORD, f"link {len(links)}'s flaps"),
            ) for c in GAUSS)
        links.append(Link(link_length, spine_points, spine_drag, flap_points, flap_drag, spine / 2))
        arc = arc + link_length

    internal, elastic_energy, fold_angle = _internal_torques(morphology, joints, q, psi, Q_rate, P, width, link_lengths)
    net_buoyancy = (rho - rho_s) * grav  # per unit volume, along +y
    solution = solve_chain(links, ChainMotion(
        theta0, theta0_rate, theta0_accel, flow_speed, q, Q_rate[:n_joints], internal[:n_joints],
        psi, Q_rate[n_joints:], internal[n_joints:]), net_buoyancy, DragRule(drag_points, drag_split),
        None if wake == "none" else WakeLaw(wake, P.get("wake_forcing"), P.get("wake_decay_widths"), width))
    Q_accel = ca.vertcat(solution.joint_accels, solution.fold_accels)
    # Buoyancy energy counted from the position of least potential a point can reach (no point is
    # farther than l + w from the root), so that the energy is never negative.
    buoyancy_energy = ca.fabs(net_buoyancy) * (length + width) * solution.volume_m3 - net_buoyancy * solution.volume_height_m4
    tip_x, tip_y = solution.tip_m

    states = [Variable(f"joint_{k}_rad", "rad", f"relative angle of bending joint {k} (0 = root side)") for k in range(n_joints)]
    if morphology == "spanwise":
        states[n_in] = Variable(f"joint_{n_in}_rad", "rad", "relative angle of the spanwise hinge (fold < 0)")
    states += [Variable(f"flap_{k}_rad", "rad", f"fold angle of the chordwise flaps on link {k}") for k in range(n_flaps)]
    states += [Variable(s.name.replace("_rad", "_rate_rad_s"), "rad/s", "rate of " + s.name) for s in list(states)]
    states += wake_states
    inputs = (
        Variable("root_angle_rad", "rad", "root (actuator) angle θ0 from the x axis"),
        Variable("root_rate_rad_s", "rad/s", "root angular rate"),
        Variable("root_accel_rad_s2", "rad/s2", "root angular acceleration"),
        Variable("flow_speed_m_s", "m/s", "body speed along +y (the fluid moves at -y relative to the root)"),
    )
    outputs = (
        Variable("thrust_N", "N", "tared load-cell force along +y at the root"),
        Variable("root_torque_Nm", "N.m", "torque the actuator applies about the root"),
        Variable("tip_x_m", "m", "tip position along x"),
        Variable("tip_y_m", "m", "tip position along y (thrust axis)"),
        Variable("flap_angle_rad", "rad", "fold angle: mean over chordwise flaps, spanwise hinge fold; 0 plain"),
        Variable("mechanical_energy_J", "J", "structure and fluid kinetic, elastic and buoyancy energy (root frame)"),
        Variable("drag_thrust_N", "N", "the drag part of thrust_N (the rest, the momentum change, averages to zero)"),
        Variable("momentum_y_Ns", "N.s",
                 "structure momentum (root frame) plus fluid impulse along +y: thrust_N = drag_thrust_N minus its "
                 "rate while the body speed is steady"),
        Variable("surge_mass_kg", "kg",
                 "mass that moves with the root along y, structure plus the added mass of each point's normal "
                 "along y; a body carrying the feather adds it to its inertia (thrust_N is the force on a root "
                 "that does not accelerate)"),
    )
    output_exprs = [solution.thrust_N, solution.root_torque_Nm, tip_x, tip_y, fold_angle,
                    solution.kinetic_energy_J + elastic_energy + buoyancy_energy, solution.drag_thrust_N,
                    solution.momentum_y_Ns, solution.surge_mass_kg]
    if wake != "none":
        outputs += (
            Variable("wake_energy_J", "J", "kinetic energy of the water the strips drag along (not in mechanical_energy_J)"),
            Variable("fluid_dissipation_W", "W",
                     "power the drag loses in the water: the plate's motion relative to its wake plus the wake's decay"),
        )
        output_exprs += [solution.wake_energy_J, solution.dissipation_W]
    n_rates = 2 * Q.numel() + len(wake_symbols)
    # Merge structurally equal subexpressions built separately per point: halves the generated C.
    xdot, outputs_expr = ca.vertsplit(
        ca.cse(ca.vertcat(Q_rate, Q_accel, solution.wake_rates, *output_exprs)), [0, n_rates, n_rates + len(output_exprs)])
    return Model(
        name=f"feather_{morphology}",
        description=f"{morphology} feather, {n_units} units, flapped at the root in water"
                    + ("" if wake == "none" else f", with a wake ('{wake}' decay)"),
        states=tuple(states),
        inputs=inputs,
        parameters=tuple(parameters),
        outputs=outputs,
        x=ca.vertcat(Q, Q_rate, *wake_symbols),
        u=ca.vertcat(theta0, theta0_rate, theta0_accel, flow_speed),
        p=p,
        xdot=xdot,
        y=outputs_expr,
        options={"morphology": morphology, "n_units": n_units, "drag_points": drag_points, "drag_split": drag_split,
                 "wake": wake,
                 **({"root_support": supported} if morphology == "spanwise" else {})},
    )


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
