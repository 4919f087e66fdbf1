"""Direct CasADi integration of a Model: the reference the FMUs and the master are checked against.

Inputs are written into the ODE as expressions of time (`drive`), not sampled: a piecewise
constant input on a grid caps accuracy at the grid's resolution and makes CVODES fail at tight
tolerances (toolchain notes).
"""
from __future__ import annotations

from typing import Callable, Mapping, Sequence

import casadi as ca
import numpy as np

from .model import Model

Drive = Callable[[ca.SX], ca.SX]


def integrate(
    model: Model,
    grid_s: Sequence[float],
    drive: Drive | None = None,
    parameters: Mapping[str, float] | None = None,
    initial_state: Sequence[float] | None = None,
    *,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    max_steps: int = 1_000_000,
) -> tuple[np.ndarray, np.ndarray]:
    """States and outputs on `grid_s` (arrays of shape (len(grid), n)); grid_s[0] is the start time.

    `drive(t)` gives the input vector as a CasADi expression of time (zeros when None).
    """
    grid = np.asarray(grid_s, dtype=float)
    t = ca.SX.sym("t")
    u = drive(t) if drive is not None else ca.SX.zeros(model.u.numel())
    p_values = model.parameter_vector(parameters)
    xdot, y = model.function()(model.x, u, p_values)
    solver = ca.integrator(
        "reference", "cvodes", {"x": model.x, "t": t, "ode": xdot}, grid[0], grid[1:],
        {"reltol": rtol, "abstol": atol, "max_num_steps": max_steps},
    )
    x0 = np.asarray(initial_state if initial_state is not None else model.initial_state(), dtype=float)
    states = np.hstack([x0[:, None], np.array(solver(x0=x0)["xf"])])
    outputs = ca.Function("outputs", [model.x, t], [y]).map(len(grid))(states, grid.reshape(1, -1))
    return states.T, np.array(outputs).T
