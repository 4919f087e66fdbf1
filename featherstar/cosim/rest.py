"""Start at rest: the continuous state in which nothing moves, for the inputs at the start.

A model's start values are whatever its author wrote down; for a feather they are the straight
sheet, which is not at rest in water (it sags under its net buoyancy, then rings). A bench that
was switched on and left alone sits at rest: every continuous state's derivative is zero
(Modelica's steady-state initialisation, `der(x) = 0`). `solve_rest` finds that state for the
strong coupling's ODE, y' = f(t0, y), by Newton's method with a finite-difference Jacobian,
from the start values:

- the step is the least-squares one, in tolerance-scaled states, so a state the derivatives do
  not depend on (a body's position on a rail) keeps its start value instead of making the
  Jacobian singular;
- a step that does not reduce the residual is halved (the one-way stops of the hinged feathers
  are steep);
- "at rest" means every state moves less than its own tolerance (rtol·|y| + atol) in a second.

When no such state exists (an input that moves at the start: a servo told to go elsewhere, a
stroke whose root accelerates at t0) the solve fails and says which state would not come to rest.
"""
from __future__ import annotations

import ctypes
from ctypes import c_double
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from .errors import StepError

#: Newton iterations before the solve gives up (it converges in a handful from a straight feather).
MAX_ITERATIONS = 40
#: Step halvings per iteration before the solve gives up.
MAX_HALVINGS = 20


@dataclass(frozen=True)
class Rest:
    """The state at rest, and how it was found."""

    y: np.ndarray
    iterations: int
    evaluations: int
    worst_rate_per_tolerance: float  # max |dy/dt| / (rtol|y| + atol), in 1/s


def solve_rest(rhs: Callable[[float, int, int], int], t0: float, y0: Sequence[float], rtol: float, atol: float,
               state_names: Sequence[str]) -> Rest:
    """The state y near y0 with rhs(t0, y) = 0 (`rhs(t, y_address, ydot_address)`, CVODE's
    form, returning 0 on success). `state_names` ("block.state") name a state that will not
    come to rest in the StepError raised then."""
    n = len(y0)
    y_buf, f_buf = (c_double * n)(), (c_double * n)()
    y_address, f_address = ctypes.addressof(y_buf), ctypes.addressof(f_buf)
    evaluations = 0

    def f(y: np.ndarray) -> np.ndarray:
        nonlocal evaluations
        evaluations += 1
        y_buf[:] = y.tolist()
        status = rhs(t0, y_address, f_address)
        out = np.array(f_buf[:], dtype=float)
        if status != 0 or not np.all(np.isfinite(out)):
            return np.full(n, np.inf)
        return out

    y = np.array(y0, dtype=float)
    scale = rtol * np.abs(y) + atol          # the tolerance of each state, fixed at the start values
    fy = f(y)
    if not np.all(np.isfinite(fy)):
        raise StepError("master", t0, "the derivatives at the start values are not finite",
                        function="start_at_rest", cause="the model cannot be evaluated at its start values")

    def size(residual: np.ndarray) -> float:
        return float(np.max(np.abs(residual) / (rtol * np.abs(y) + atol)))

    for iteration in range(1, MAX_ITERATIONS + 1):
        if size(fy) <= 1.0:
            return Rest(y, iteration - 1, evaluations, size(fy))
        jacobian = np.empty((n, n))
        for j in range(n):
            h = 1e-7 * max(abs(y[j]), scale[j] / rtol)
            yj = y.copy()
            yj[j] += h
            jacobian[:, j] = (f(yj) - fy) / h
        if not np.all(np.isfinite(jacobian)):
            break
        # least squares in tolerance-scaled states: undetermined states keep their values
        step = np.linalg.lstsq(jacobian * scale, -fy, rcond=1e-12)[0] * scale
        norm = np.linalg.norm(fy / scale)
        for _ in range(MAX_HALVINGS):
            trial = y + step
            f_trial = f(trial)
            if np.all(np.isfinite(f_trial)) and np.linalg.norm(f_trial / scale) < norm:
                y, fy = trial, f_trial
                break
            step = 0.5 * step
        else:
            break
    worst = int(np.argmax(np.abs(fy) / (rtol * np.abs(y) + atol))) if np.all(np.isfinite(fy)) else 0
    name = state_names[worst] if worst < len(state_names) else f"x{worst}"
    block = name.split(".", 1)[0]
    raise StepError(block, t0, f"cannot start at rest: state {name} keeps changing at "
                    f"{fy[worst]:.3g}/s after {evaluations} evaluations",
                    function="start_at_rest",
                    cause="no state in which nothing moves for the inputs at the start (an input that moves at "
                    "t0, e.g. a servo commanded away from its start or a stroke accelerating at t0, or a model "
                    "without an equilibrium); set master.start_at_rest = false to start from the start values")
