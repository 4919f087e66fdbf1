"""A model is symbolic data: named states, inputs, parameters and outputs plus CasADi expressions.

No numbers are integrated here and nothing is exported: `featherstar.fmu_src.export` turns a Model into an
FMU, `featherstar.fmu_src.integrate` integrates it directly. Models are explicit ODEs (xdot = f(x, u, p),
y = g(x, u, p)) because CasADi's exported FMUs never solve algebraic equations.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from typing import Callable, Mapping

import casadi as ca

from .errors import ModelError


@dataclass(frozen=True)
class Variable:
    """A state, input or output. `start` is the initial value of a state or the default of an input."""

    name: str
    unit: str
    description: str
    start: float = 0.0


@dataclass(frozen=True)
class Parameter:
    """A physical constant of a model, tunable through the FMU; valid values lie in [minimum, maximum].

    `exclusive_minimum` makes the lower bound strict (a length must be > 0, not >= 0); `choices`,
    when given, lists the only values allowed (a switch).
    """

    name: str
    default: float
    unit: str
    minimum: float
    maximum: float
    description: str
    exclusive_minimum: bool = False
    choices: tuple[float, ...] | None = None

    def check(self, value: float) -> None:
        if self.choices is not None and value not in self.choices:
            raise ModelError(
                f"parameter '{self.name}' = {value!r} must be one of {', '.join(f'{c:g}' for c in self.choices)} "
                f"({self.description})"
            )
        low_ok = value > self.minimum if self.exclusive_minimum else value >= self.minimum
        if not (math.isfinite(value) and low_ok and value <= self.maximum):
            bracket = "(" if self.exclusive_minimum else "["
            raise ModelError(
                f"parameter '{self.name}' = {value!r} {self.unit} is outside its valid range "
                f"{bracket}{self.minimum:g}, {self.maximum:g}] {self.unit} ({self.description})"
            )


@dataclass(frozen=True)
class Model:
    """An explicit ODE model with named, unit-carrying variables.

    x, u, p are column SX symbols; xdot and y are expressions of (x, u, p).
    `options` holds the build options (those that change the equations' structure, e.g. the
    number of units); together with the expressions they define the build cache key.
    """

    name: str
    description: str
    states: tuple[Variable, ...]
    inputs: tuple[Variable, ...]
    parameters: tuple[Parameter, ...]
    outputs: tuple[Variable, ...]
    x: ca.SX
    u: ca.SX
    p: ca.SX
    xdot: ca.SX
    y: ca.SX
    options: Mapping[str, object] = field(default_factory=dict)
    #: Checks across parameters (e.g. a four-bar must close); each raises ModelError.
    constraints: tuple[Callable[[Mapping[str, float]], None], ...] = ()

    def __post_init__(self) -> None:
        for group, symbol in (("states", self.x), ("inputs", self.u), ("parameters", self.p)):
            if len(getattr(self, group)) != symbol.numel():
                raise ModelError(f"model '{self.name}': {group} names and symbols disagree in size")
        if self.xdot.numel() != self.x.numel() or self.y.numel() != len(self.outputs):
            raise ModelError(f"model '{self.name}': xdot/y sizes do not match states/outputs")
        names = [v.name for v in (*self.states, *self.inputs, *self.parameters, *self.outputs)]
        duplicates = {n for n in names if names.count(n) > 1}
        if duplicates:
            raise ModelError(f"model '{self.name}': duplicate variable names {sorted(duplicates)}")

    def function(self) -> ca.Function:
        """ode(x, u, p) -> (xdot, y) as a CasADi Function."""
        return ca.Function(
            self.name, [self.x, self.u, self.p], [self.xdot, self.y], ["x", "u", "p"], ["xdot", "y"]
        )

    def default_parameters(self) -> dict[str, float]:
        return {p.name: p.default for p in self.parameters}

    def parameter_vector(self, overrides: Mapping[str, float] | None = None) -> list[float]:
        """Defaults with `overrides` applied, each checked against its physical range."""
        values = self.default_parameters()
        for name, value in (overrides or {}).items():
            if name not in values:
                raise ModelError(
                    f"model '{self.name}' has no parameter '{name}'; it has: {', '.join(values)}"
                )
            values[name] = float(value)
        for parameter in self.parameters:
            parameter.check(values[parameter.name])
        for constraint in self.constraints:
            constraint(values)
        return [values[p.name] for p in self.parameters]

    def initial_state(self) -> list[float]:
        return [s.start for s in self.states]

    def fingerprint(self) -> str:
        """Hash of the equations, variable metadata and options: the FMU build cache key."""
        digest = hashlib.sha256()
        digest.update(self.function().serialize().encode())
        for group in (self.states, self.inputs, self.parameters, self.outputs):
            digest.update(repr(group).encode())
        digest.update(repr(sorted(self.options.items())).encode())
        return digest.hexdigest()[:16]
