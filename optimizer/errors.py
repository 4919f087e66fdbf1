"""Errors of the optimizer package (see the tree in featherstar.fmu_src.errors)."""
from __future__ import annotations

from ..fmu_src.errors import FeatherstarError


class OptimizerError(FeatherstarError):
    """A search space, its bounds, an evaluation log or a sweep request is unusable."""
