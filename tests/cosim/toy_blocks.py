"""Python blocks for the master's tests (loaded by scenes as kind = "python")."""
from __future__ import annotations

import math
from typing import Mapping

from featherstar.cosim.framework.block import Port


class Integrator:
    """y = ∫ u dt (explicit Euler over the macro step), with rollback support."""

    def __init__(self, name: str, y0: float = 0.0) -> None:
        self.name = name
        self.inputs = {"u": Port("u", "1")}
        self.outputs = {"y": Port("y", "1")}
        self.y = float(y0)
        self.u = 0.0

    def start(self, t0_s: float) -> None:
        pass

    def set_inputs(self, values: Mapping[str, float]) -> None:
        self.u = values.get("u", self.u)

    def get_outputs(self) -> dict[str, float]:
        return {"y": self.y}

    def do_step(self, t_s: float, h_s: float) -> None:
        self.y += h_s * self.u

    def get_state(self) -> object:
        return self.y

    def set_state(self, state: object) -> None:
        self.y = float(state)  # type: ignore[arg-type]

    def close(self) -> None:
        pass


class Poison:
    """Memoryless pass-through that returns NaN from t_bad on (a failing sensor or model)."""

    can_iterate = True

    def __init__(self, name: str, t_bad: float = 0.5) -> None:
        self.name = name
        self.t_bad = float(t_bad)
        self.inputs = {"u": Port("u", "N")}
        self.outputs = {"y": Port("y", "N", depends_on=("u",))}
        self.u = 0.0
        self.t = 0.0

    def evaluate(self, t_s: float, inputs: Mapping[str, float]) -> dict[str, float]:
        return {"y": math.nan if t_s >= self.t_bad else inputs["u"]}

    def start(self, t0_s: float) -> None:
        pass

    def set_inputs(self, values: Mapping[str, float]) -> None:
        pass

    def get_outputs(self) -> dict[str, float]:
        return {"y": 0.0}

    def do_step(self, t_s: float, h_s: float) -> None:
        pass

    def close(self) -> None:
        pass
