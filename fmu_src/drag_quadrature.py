"""Quadrature of quadratic drag along a line of a rigid plate on which the normal speed is affine.

Drag per unit length is −f |s| s with s the normal speed relative to the water (and to its wake),
and on a rigid plate s is affine along any straight line. |s| s is then a quadratic on either side
of the zero of s and is not a polynomial across it: Gauss–Legendre points converge slowly (as
n^−2: the integrand's second derivative jumps) whenever s changes sign on the line, which a
folding flap does over much of each stroke. Splitting the line at the zero of s and using Gauss
points on each side integrates |s| s and its first moment exactly with 2 points a side (cubics on
each piece), so the only error left is that of the drag factor f varying along the line (C_d(KC)
with the span). `bench/drag_convergence.py` measures both rules on the feathers.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np


@dataclass(frozen=True)
class DragRule:
    """`points` Gauss–Legendre points on the line, or on each side of the zero of s with `split`."""

    points: int
    split: bool

    def nodes(self, speed_start: ca.SX, speed_end: ca.SX) -> list[tuple[ca.SX, ca.SX]]:
        """(t, weight) pairs on [0, 1] for a line whose normal speed runs from `speed_start` to
        `speed_end`; the weights add up to 1."""
        unit = _gauss_legendre_unit(self.points)
        if not self.split:
            return [(float(t), float(w)) for t, w in unit]
        crosses = speed_start * speed_end < 0
        # Where s does not change sign the zero is put at the line's end: the second piece then
        # has zero length. The denominator is guarded so that no branch divides by zero.
        zero = ca.if_else(crosses, speed_start / ca.if_else(crosses, speed_start - speed_end, 1.0), 1.0)
        return ([(zero * t, zero * w) for t, w in unit]
                + [(zero + (1 - zero) * t, (1 - zero) * w) for t, w in unit])


@lru_cache(maxsize=None)
def _gauss_legendre_unit(points: int) -> tuple[tuple[float, float], ...]:
    nodes, weights = np.polynomial.legendre.leggauss(points)
    return tuple((0.5 * (1 + t), 0.5 * w) for t, w in zip(nodes, weights))
