"""Four-bar linkage in closed form (Freudenstein), symbolic so rates and accelerations are exact.

Links: a = crank (input, on the servo), b = coupler, c = rocker (output, the feather root),
d = ground. With crank angle θ2 measured from the ground link,
    K1 cos θ4 − K2 cos θ2 + K3 = cos(θ2 − θ4),  K1 = d/a, K2 = d/c, K3 = (a² − b² + c² + d²)/(2ac),
solved as θ4 = 2 atan2(−B + σ√(B² − 4AC), 2A) with σ = −1 for the open assembly used here.
"""
from __future__ import annotations

import math

import casadi as ca

from .errors import ModelError

#: Transmission angles outside this band make the output badly conditioned (small force
#: transmission, large sensitivity to link tolerances); the usual design rule is 40–140°.
TRANSMISSION_LIMITS_DEG = (40.0, 140.0)


def rocker_angle(theta2, a, b, c, d, branch: float = -1.0):
    """Output angle θ4 for crank angle θ2; works on floats and CasADi symbols."""
    k1, k2, k3 = d / a, d / c, (a**2 - b**2 + c**2 + d**2) / (2 * a * c)
    cos2, sin2 = ca.cos(theta2), ca.sin(theta2)
    big_a = cos2 - k1 - k2 * cos2 + k3
    big_b = -2 * sin2
    big_c = k1 - (k2 + 1) * cos2 + k3
    return 2 * ca.atan2(-big_b + branch * ca.sqrt(big_b**2 - 4 * big_a * big_c), 2 * big_a)


def transmission_angle(theta2: float, a: float, b: float, c: float, d: float) -> float:
    """Angle between coupler and rocker (rad) by the law of cosines on the crank-ground diagonal."""
    diagonal_sq = a**2 + d**2 - 2 * a * d * math.cos(theta2)
    return math.acos(max(-1.0, min(1.0, (b**2 + c**2 - diagonal_sq) / (2 * b * c))))


def check_linkage(a: float, b: float, c: float, d: float, crank_neutral_rad: float, crank_range_rad: float) -> None:
    """Refuse a linkage that is not Grashof with a crank-side shortest link, or whose transmission
    angle leaves 40–140° anywhere in the crank's working range."""
    links = {"crank_m": a, "coupler_m": b, "rocker_m": c, "ground_m": d}
    for name, value in links.items():
        if not (math.isfinite(value) and value > 0):
            raise ModelError(f"four-bar link '{name}' = {value!r} m must be > 0")
    ordered = sorted(links.values())
    if ordered[0] + ordered[3] > ordered[1] + ordered[2]:
        raise ModelError(
            "four-bar is non-Grashof (shortest + longest > sum of the other two): "
            f"{links}; no link can rotate fully and the mechanism locks inside its range"
        )
    low, high = (math.radians(v) for v in TRANSMISSION_LIMITS_DEG)
    for k in range(41):
        theta2 = crank_neutral_rad + crank_range_rad * (k / 20.0 - 1.0)
        mu = transmission_angle(theta2, a, b, c, d)
        if not low <= mu <= high:
            raise ModelError(
                f"four-bar badly conditioned: transmission angle {math.degrees(mu):.1f}° at crank "
                f"angle {math.degrees(theta2):.1f}° is outside {TRANSMISSION_LIMITS_DEG} deg "
                f"(links {links}, crank range ±{math.degrees(crank_range_rad):.0f}°)"
            )
