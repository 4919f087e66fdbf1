"""Which fitted coefficients the recordings identify.

A fit can match the recordings well (R² 0.99) while a coefficient is free to move: it has no
effect on the recorded thrust (the stroke does not excite it), or another coefficient trades off
against it (their effects on the thrust are nearly proportional), so the recordings fix only a
combination. Both show in the Gauss–Newton covariance at the optimum (featherstar.optimizer.
calibration.fit): an infinite or large standard deviation, or a correlation near ±1.

The covariance is a local, linear picture, and its sd are lower bounds where samples are
correlated (fit.py's docstring), so these flags catch the plain cases, not every weak one; a
profile of the misfit along a flagged coefficient would show the valley's shape, at one
simulation per profile point.
"""
from __future__ import annotations

import math

from .fit import Calibration

#: Two coefficients correlated beyond this are not told apart by the recordings.
MAX_CORRELATION = 0.95
#: A coefficient whose sd exceeds this share of its value is not pinned down by the recordings
#: (the 15 % accuracy a calibration is checked against would be inside one sd).
MAX_RELATIVE_SD = 0.15


def unidentified(calibration: Calibration) -> dict[str, str]:
    """{coefficient: why} for each fitted coefficient the recordings do not identify (empty when
    every one is identified)."""
    names = list(calibration.values)
    reasons: dict[str, str] = {}
    for i, name in enumerate(names):
        value, sd = calibration.values[name], calibration.sd[name]
        why = []
        if not math.isfinite(sd):
            why.append("sd not finite: the recorded thrust does not depend on it")
        elif sd > MAX_RELATIVE_SD * abs(value):
            share = f"{sd / abs(value):.0%} of its value" if value else "its value is 0"
            why.append(f"sd {sd:.3g} is {share} (limit {MAX_RELATIVE_SD:.0%})")
        for j, other in enumerate(names):
            r = calibration.correlation[i][j]
            # (a coefficient without effect has no correlation: it is flagged on its own)
            if j != i and math.isfinite(sd) and math.isfinite(calibration.sd[other]) \
                    and not (math.isfinite(r) and abs(r) <= MAX_CORRELATION):
                why.append(f"correlation {r:+.3f} with {other} (limit ±{MAX_CORRELATION:g}): only a "
                           "combination of the two is fitted")
        if why:
            reasons[name] = "; ".join(why)
    return reasons
