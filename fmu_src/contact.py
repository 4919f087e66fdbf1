"""One-way penalty contact for hinge stops (physics spec §3).

With penetration d, the stop pushes back with k·δ(d) + c·ḋ·min(d/ε, 1), where δ is 0 for d ≤ 0,
d²/(2ε) below ε and d − ε/2 beyond: C¹, and exactly zero before contact. A softplus would be
smoother but pushes flaps open by several degrees before they ever touch. The total is clipped at
zero so the damper never pulls the surfaces together (no sticking on release).
"""
from __future__ import annotations

import casadi as ca


def one_way_stop(
    penetration: ca.SX, penetration_rate: ca.SX, stiffness: ca.SX, damping: ca.SX, smoothing: ca.SX
) -> tuple[ca.SX, ca.SX]:
    """(restoring torque >= 0 acting to reduce `penetration`, stored elastic energy)."""
    d, eps = penetration, smoothing
    engaged = d > 0
    ramp = d < eps
    shape = ca.if_else(engaged, ca.if_else(ramp, d**2 / (2 * eps), d - eps / 2), 0)
    energy = ca.if_else(
        engaged, ca.if_else(ramp, d**3 / (6 * eps), eps**2 / 6 + (d**2 - eps**2) / 2 - eps * (d - eps) / 2), 0
    )
    damping_share = ca.if_else(engaged, ca.fmin(d / eps, 1), 0)
    torque = ca.fmax(stiffness * shape + damping * penetration_rate * damping_share, 0)
    return torque, stiffness * energy
