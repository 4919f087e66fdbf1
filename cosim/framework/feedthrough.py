"""Direct feedthrough of a fmu_src Model: which inputs each output reads at the same instant,
exact from the CasADi Jacobian's sparsity (the scene checks and the FMU adapter both use it)."""
from __future__ import annotations

from typing import Any


def model_feedthrough(model: Any) -> dict[str, tuple[str, ...]]:
    """For each output of a fmu_src Model, the inputs it depends on directly (exact sparsity)."""
    import casadi as ca

    if model.u.numel() == 0:
        return {v.name: () for v in model.outputs}
    sp = ca.jacobian(model.y, model.u).sparsity()
    rows, cols = sp.get_triplet()
    deps: dict[str, list[str]] = {v.name: [] for v in model.outputs}
    for r, c in zip(rows, cols):
        deps[model.outputs[r].name].append(model.inputs[c].name)
    return {k: tuple(v) for k, v in deps.items()}
