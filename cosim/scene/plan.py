"""The Plan: what `featherstar.cosim.scene.graph.plan` makes of a scene (resolved blocks, wiring,
pruning, deduplication, loops), data only; the checks and the couplings read it."""
from __future__ import annotations

from dataclasses import dataclass, field

from .block_kind import ResolvedBlock
from .data import Scene
from .specs import PortRef


@dataclass(frozen=True)
class Loop:
    """An algebraic loop: the inputs on it (tear variables) and one cycle, port by port."""

    blocks: tuple[str, ...]
    inputs: tuple[PortRef, ...]
    outputs: tuple[PortRef, ...]
    cycle: tuple[PortRef, ...]

    def describe(self) -> str:
        return " -> ".join(str(p) for p in (*self.cycle, self.cycle[0]))


@dataclass
class Plan:
    scene: Scene
    blocks: dict[str, ResolvedBlock]  # every block of the scene, resolved
    instantiate: list[str]  # blocks the run builds (pruned, deduplicated), in scene order
    alias_of: dict[str, str]  # every needed block -> the block that computes it
    source_of: dict[PortRef, PortRef]  # input -> driving output (as written in the scene)
    requested: list[PortRef]  # signals to record, as named by the user
    loops: list[Loop]
    period_s: float | None
    t_end_s: float
    pruned: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def canonical(self, ref: PortRef) -> PortRef:
        """The output that actually computes signal `ref` (after deduplication)."""
        return PortRef(self.alias_of.get(ref.block, ref.block), ref.port)

    def driver(self, dst: PortRef) -> PortRef:
        return self.canonical(self.source_of[dst])
