"""What every block kind resolves a block to (`ResolvedBlock`), and the kinds' base class.

The kinds themselves: featherstar.cosim.scene.blocks (recorder, constant, gain, and the registry),
.python_blocks (python), .fmu_blocks (fmu); the swimmer adds `stroke` (featherstar.cosim.swimmer.kinds).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Hashable, Mapping

from ..errors import SceneError
from ..framework.block import Passivity, Port
from .specs import BlockSpec, PortRef, parse_value


@dataclass
class ResolvedBlock:
    """A block's build artefact: ports and capabilities, plus what is needed to instantiate it."""

    spec: BlockSpec
    inputs: dict[str, Port]
    outputs: dict[str, Port]
    memoryless: bool = False
    iterable: bool = False
    continuous: bool = False  # may join the strong (one-ODE) group
    identity: Hashable | None = None  # equal identities + equal input sources => interchangeable
    period_s: float | None = None
    model: Any = None  # fmu_src Model for model-backed blocks
    parameters: dict[str, Any] = field(default_factory=dict)  # models: floats; FMU files: each variable's type
    fmu_path: Path | None = None
    fmu_info: Any = None
    obj: Any = None  # python block object (stroke, gain, python kinds)
    signals: tuple[PortRef, ...] = ()  # recorder
    records_only: bool = False  # a recorder: names signals to record, computes nothing
    can_rollback: bool = False  # its state can be saved and restored (the adaptive weak master rejects steps)
    gives_period: bool = False  # its period_s is the scene's period (run length, metric window)
    ramps_s: tuple[tuple[float, str], ...] = ()  # its fastest transitions (s, the setting naming each): step guards
    shared_parameters: Mapping[str, float] = field(default_factory=dict)  # given to model blocks leaving them unset
    passivity: Passivity | None = None  # a passive block's energy output and power ports (the energy guard)
    notes: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.spec.name


class BlockKind:
    name = ""

    def resolve(self, spec: BlockSpec) -> ResolvedBlock:
        raise NotImplementedError

    def override(self, spec: BlockSpec, key: str, raw: Any) -> BlockSpec:
        return dataclasses.replace(spec, overrides=spec.overrides.set(key, parse_value(raw)))

    def override_batch(self, spec: BlockSpec, items: Mapping[str, Any]) -> BlockSpec:
        """Apply one batch of overrides (one `with_overrides` call) to a block."""
        problems = []
        for key, raw in items.items():
            try:
                spec = self.override(spec, key, raw)
            except SceneError as exc:
                problems.extend(exc.problems)
        if problems:
            raise SceneError(problems)
        return spec


def where(spec: BlockSpec) -> str:
    return f"block '{spec.name}' ({spec.kind})"
