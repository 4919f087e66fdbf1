"""How an FMU file's ports enter a scene's plan (featherstar.cosim.scene.graph): FMI 3.0 arrays connected or
recorded whole expand to their elements; unconnected inputs keep the FMU's start values (they
leave the block's ports, so they never block a scene); outputs nothing reads are never
evaluated."""
from __future__ import annotations

import dataclasses
from typing import Iterable

from ..framework.block import passivity_by_convention
from .block_kind import ResolvedBlock
from .data import Connection, PortRef
from .plan import Plan


def _arrays(rb: ResolvedBlock | None) -> dict[str, list[str]]:
    info = rb.fmu_info if rb is not None else None
    return dict(getattr(info, "arrays", None) or {})


def expand_array_connections(connections: Iterable[Connection], resolved: dict[str, ResolvedBlock],
                              problems: list[str]) -> list[Connection]:
    """A connection between two whole FMI 3 arrays becomes one connection per element; elements
    (`v[2]`) connect like scalars."""
    out = []
    for conn in connections:
        src_arrays, dst_arrays = _arrays(resolved.get(conn.src.block)), _arrays(resolved.get(conn.dst.block))
        src_elems, dst_elems = src_arrays.get(conn.src.port), dst_arrays.get(conn.dst.port)
        if src_elems is None and dst_elems is None:
            out.append(conn)
        elif src_elems is not None and dst_elems is not None and len(src_elems) == len(dst_elems):
            out.extend(Connection(PortRef(conn.src.block, a), PortRef(conn.dst.block, b))
                       for a, b in zip(src_elems, dst_elems))
        else:
            def shape(elems: list[str] | None) -> str:
                return f"an array of {len(elems)}" if elems is not None else "a scalar"
            problems.append(f"connection '{conn}': {conn.src} is {shape(src_elems)} but {conn.dst} is "
                            f"{shape(dst_elems)}; connect arrays of the same size, or elements such as "
                            f"{conn.src.block}.{(src_elems or dst_elems or ['v[0]'])[0]}")
    return out


def expand_array_refs(refs: list[PortRef], resolved: dict[str, ResolvedBlock]) -> list[PortRef]:
    """Recording a whole array records each of its elements."""
    out = []
    for ref in refs:
        elems = _arrays(resolved.get(ref.block)).get(ref.port)
        out.extend(PortRef(ref.block, e) for e in elems) if elems else out.append(ref)
    return out


def hold_unconnected_inputs(rb: ResolvedBlock, dangling: set[str]) -> None:
    """An FMU file's unconnected inputs keep their start values: they leave the block's ports."""
    rb.inputs = {k: v for k, v in rb.inputs.items() if k not in dangling}
    rb.outputs = {k: dataclasses.replace(v, depends_on=tuple(d for d in v.depends_on if d not in dangling))
                  for k, v in rb.outputs.items()}
    rb.fmu_info = dataclasses.replace(rb.fmu_info, inputs=dict(rb.inputs), outputs=dict(rb.outputs))
    rb.passivity = passivity_by_convention(rb.inputs, rb.outputs)  # power ports it still has


def keep_used_outputs(p: "Plan") -> None:
    """An FMU file's outputs that nothing reads are never evaluated (whatever their type); the
    passive-energy guard reads a passive block's energy and power-port outputs (featherstar.cosim.scene.guards)."""
    used: dict[str, set[str]] = {}
    for dst, src in p.source_of.items():
        if p.alias_of.get(dst.block) == dst.block:
            c = p.canonical(src)
            used.setdefault(c.block, set()).add(c.port)
    for ref in p.requested:
        c = p.canonical(ref)
        used.setdefault(c.block, set()).add(c.port)
    for name in p.instantiate:
        rb = p.blocks[name]
        if rb.fmu_info is not None and rb.model is None:
            keep = used.get(name, set())
            if rb.passivity is not None and p.scene.master.passive_energy_factor > 0:
                keep = keep | {rb.passivity.energy_output, *(out for out, _ in rb.passivity.power_ports)}
            rb.fmu_info = dataclasses.replace(rb.fmu_info, outputs={k: v for k, v in rb.outputs.items() if k in keep})
