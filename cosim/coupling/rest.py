"""Start at rest: the continuous state in which nothing moves, for the inputs at the start.

A model's start values are whatever its author wrote down; for a feather they are the straight
sheet, which is not at rest in water (it sags under its net buoyancy, then rings). A bench that
was switched on and left alone sits at rest: every continuous state's derivative is zero
(Modelica's steady-state initialisation, `der(x) = 0`). `solve_rest` finds that state for the
strong coupling's ODE, y' = f(t0, y), from the start values, as the least-squares problem
min |f(t0, y) / tol|, tol = rtol·|y0| + atol, with variables scaled by tol too:

- a trust-region method (scipy's dogbox), not plain Newton: the hinged feathers' one-way stops
  are steep, smoothed kinks at zero fold, where full Newton steps overshoot and a line search
  crawls (a spanwise feather: 40 iterations at step 1e-3 without converging);
- the trust-region step solves the linear subproblem in the least-squares sense, so a state the
  derivatives do not depend on (a body's position on a rail) keeps its start value;
- "at rest" means every state moves less than its own tolerance in a second.

When no such state exists (an input that keeps pushing, a model without an equilibrium) the
solve fails and says which state would not come to rest.
"""
from __future__ import annotations

import ctypes
from ctypes import c_double
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares

from ..errors import StepError

#: Function evaluations before the solve gives up (a feather converges in tens to hundreds).
MAX_EVALUATIONS = 20000


@dataclass(frozen=True)
class Rest:
    """The state at rest, and how it was found."""

    y: np.ndarray
    evaluations: int  # of the right-hand side, finite-difference Jacobians included
    worst_rate_per_tolerance: float  # max |dy/dt| / (rtol|y| + atol), in 1/s


def solve_rest(rhs: Callable[[float, int, int], int], t0: float, y0: Sequence[float], rtol: float, atol: float,
               state_names: Sequence[str]) -> Rest:
    """The state y near y0 with rhs(t0, y) = 0 (`rhs(t, y_address, ydot_address)`, CVODE's
    form, returning 0 on success). `state_names` ("block.state") name a state that will not
    come to rest in the StepError raised then."""
    n = len(y0)
    y_buf, f_buf = (c_double * n)(), (c_double * n)()
    y_address, f_address = ctypes.addressof(y_buf), ctypes.addressof(f_buf)
    y_start = np.array(y0, dtype=float)
    tolerance = rtol * np.abs(y_start) + atol
    evaluations = 0

    def f(y: np.ndarray) -> np.ndarray:
        nonlocal evaluations
        evaluations += 1
        y_buf[:] = y.tolist()
        status = rhs(t0, y_address, f_address)
        out = np.array(f_buf[:], dtype=float)
        if status != 0 or not np.all(np.isfinite(out)):
            raise _NotFinite
        return out

    def worst(y: np.ndarray, fy: np.ndarray) -> tuple[float, int]:
        rate = np.abs(fy) / (rtol * np.abs(y) + atol)
        return float(np.max(rate)), int(np.argmax(rate))

    try:
        f0 = f(y_start)
    except _NotFinite:
        raise StepError("master", t0, "the derivatives at the start values are not finite",
                        function="start_at_rest", cause="the model cannot be evaluated at its start values") from None

    def scaled_residual(z: np.ndarray) -> np.ndarray:
        try:
            return f(y_start + z * tolerance) / tolerance
        except _NotFinite:   # a trial state the model cannot take: the trust region shrinks
            return np.full(n, 1e30)

    y, fy = y_start, f0
    if worst(y, fy)[0] > 1.0:
        solution = least_squares(scaled_residual, np.zeros(n), method="dogbox", xtol=1e-14, ftol=1e-14, gtol=1e-14,
                                 max_nfev=MAX_EVALUATIONS)
        y = y_start + solution.x * tolerance
        fy = scaled_residual(solution.x) * tolerance
    size, k = worst(y, fy)
    if size <= 1.0:
        return Rest(y, evaluations, size)
    name = state_names[k] if k < len(state_names) else f"x{k}"
    raise StepError(name.split(".", 1)[0], t0, f"cannot start at rest: state {name} keeps changing at "
                    f"{fy[k]:.3g}/s after {evaluations} evaluations",
                    function="start_at_rest",
                    cause="no state in which nothing moves for the inputs at the start (an input that keeps "
                    "pushing, or a model without an equilibrium); set master.start_at_rest = false to start "
                    "from the start values")


class _NotFinite(Exception):
    """The right-hand side failed or returned NaN/inf at a trial state."""
