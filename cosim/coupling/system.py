"""The runtime system of one run: the plan's wiring over the runtime units (built once per
Simulator, never changed while it runs). What changes during the run is in featherstar.cosim.coupling.context."""
from __future__ import annotations

import math
from typing import Callable, Mapping, Sequence

from ..errors import StepError
from ..framework.units import Unit
from ..scene.data import PortRef
from ..scene.plan import Plan


class System:
    """The units of a plan and how they are wired: for each input the output that drives it, for
    each output the inputs it reads at the same instant (direct feedthrough)."""

    def __init__(self, plan: Plan, units: Mapping[str, Unit]) -> None:
        self.plan = plan
        self.units: dict[str, Unit] = dict(units)
        self.master = plan.scene.master
        self.feedthrough: dict[str, dict[int, list[int]]] = {}  # unit -> output index -> input indices
        for name, u in self.units.items():
            rb = plan.blocks[name]
            self.feedthrough[name] = {}
            for k, out in enumerate(u.output_names):
                deps = rb.outputs[out].depends_on if out in rb.outputs else tuple(u.input_names)
                self.feedthrough[name][k] = [u.input_names.index(d) for d in deps if d in u.input_names]

    def output_node(self, ref: str | PortRef) -> tuple[str, int]:
        """(unit, output index) of a "block.port" output, following the plan's aliases."""
        c = self.plan.canonical(PortRef.parse(ref) if isinstance(ref, str) else ref)
        return c.block, self.units[c.block].output_names.index(c.port)

    def source_of(self, u: Unit, i: int) -> tuple[str, int]:
        """(unit, output index) driving input i of unit u."""
        return self.output_node(self.plan.driver(PortRef(u.name, u.input_names[i])))

    def input_sources(self, u: Unit) -> dict[tuple[str, int], tuple[str, int]]:
        return {(u.name, i): self.source_of(u, i) for i in range(len(u.input_names))}

    def flow_order(self, units: Sequence[Unit]) -> list[Unit]:
        """Units in signal-flow order (sources first); feedback edges broken at the latest unit."""
        names = [u.name for u in units]
        preds: dict[str, set[str]] = {n: set() for n in names}
        for u in units:
            for name in u.input_names:
                src = self.plan.driver(PortRef(u.name, name)).block
                if src != u.name:
                    preds[u.name].add(src)
        order: list[str] = []
        remaining = list(names)
        while remaining:
            ready = [n for n in remaining if not (preds[n] - set(order))]
            if not ready:  # a feedback cycle: take the unit with the fewest unmet predecessors
                ready = [min(remaining, key=lambda n: (len(preds[n] - set(order)), remaining.index(n)))]
            order.append(ready[0])
            remaining.remove(ready[0])
        return [self.units[n] for n in order]

    def output_checker(self, units: Sequence[Unit]) -> Callable[[float], None]:
        """A check that every unit's outputs are finite, in signal-flow order (the first bad one is
        the origin: downstream blocks only pass the NaN on)."""
        flow = [(u, u.outbuf, len(u.output_names)) for u in self.flow_order(units) if u.output_names]

        def check(t: float) -> None:
            for u, buf, n in flow:
                if not math.isfinite(sum(buf[:n])):
                    for i in range(n):
                        if not math.isfinite(buf[i]):
                            raise StepError(u.name, t, f"output {u.output_names[i]} = {buf[i]}",
                                            cause="the block produced NaN/inf: its model blew up, divided by zero, "
                                            "or got invalid parameters or inputs")
        return check
