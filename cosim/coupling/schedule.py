"""The schedule: the order in which inputs are set and outputs evaluated at one instant,
algebraic loops solved by Newton iteration on their inputs (shared by both couplings)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Collection, Sequence

import numpy as np

from ..errors import StepError
from ..framework.units import Unit
from ..sccs import cycle_through, strongly_connected
from .context import Context, Recording
from .system import System


class LoopSolver:
    """Newton iteration (finite-difference Jacobian) on the inputs of an algebraic loop."""

    def __init__(self, context: Context, tol: float, max_iter: int, description: str,
                 tear: list[tuple[Unit, int, Unit, int]],
                 setters: list[Callable[[], None]], getters: list[Callable[[], None]]) -> None:
        self.context = context
        self.tol, self.max_iter = tol, max_iter
        self.description = description
        self.tear = tear
        self.setters = setters
        self.getters = getters
        self.n = len(tear)
        self.v = np.array([u.inbuf[i] for u, i, _, _ in tear], dtype=float)
        self.iterations = 0
        self.solves = 0
        self.block = ",".join(dict.fromkeys(u.name for u, _, _, _ in tear))  # named in errors

    def _g(self, v: np.ndarray) -> np.ndarray:
        for j, (u, i, _, _) in enumerate(self.tear):
            u.inbuf[i] = v[j]
        for s in self.setters:
            s()
        for g in self.getters:
            g()
        return np.array([src.outbuf[k] for _, _, src, k in self.tear], dtype=float)

    def __call__(self) -> None:
        tol, max_iter = self.tol, self.max_iter
        v = self.v.copy()
        r = self._g(v) - v
        it = 0
        while True:
            scale = 1.0 + float(np.max(np.abs(v)))
            if not np.all(np.isfinite(r)):
                raise StepError(self.block, self.context.t,
                                f"algebraic loop {self.description} produced NaN/inf",
                                cause="the loop diverged; its gain may exceed 1 or the blocks are invalid here")
            if float(np.max(np.abs(r))) <= tol * scale:
                break
            if it >= max_iter:
                raise StepError(self.block, self.context.t,
                                f"algebraic loop {self.description} did not converge in {max_iter} Newton "
                                f"iterations (residual {float(np.max(np.abs(r))):.3g})",
                                cause="no solution near the previous one; break the loop with a filter")
            jac = np.empty((self.n, self.n))
            for j in range(self.n):
                d = 1e-7 * (1.0 + abs(v[j]))
                w = v.copy()
                w[j] += d
                jac[:, j] = ((self._g(w) - w) - r) / d
            try:
                if np.linalg.cond(jac) > 1e12:
                    raise np.linalg.LinAlgError
                step = np.linalg.solve(jac, -r)
            except np.linalg.LinAlgError:
                raise StepError(self.block, self.context.t,
                                f"algebraic loop {self.description} has no unique solution (singular "
                                "iteration Jacobian: the loop gain is 1)",
                                cause="an unsolvable algebraic loop; break it with a block that has state") from None
            # damped Newton: halve until the residual decreases
            lam, norm0 = 1.0, float(np.max(np.abs(r)))
            for _ in range(30):
                w = v + lam * step
                rw = self._g(w) - w
                if np.all(np.isfinite(rw)) and float(np.max(np.abs(rw))) < norm0 or lam < 1e-6:
                    break
                lam *= 0.5
            v, r = w, rw
            it += 1
        # leave every block evaluated at the solution
        self._g(v)
        self.v = v
        self.iterations += it
        self.solves += 1


@dataclass(frozen=True)
class Step:
    """One op of a schedule as data, with its Python form `run`: set inputs `indices` of `unit`
    from the outputs in `sources` (kind "set"), get outputs `indices` of `unit` ("get"), or solve
    an algebraic loop ("loop", unit None). The data lets featherstar.cosim.coupling.compiled_rhs run the
    step in C."""

    kind: str
    unit: Unit | None
    indices: tuple[int, ...]
    sources: tuple[tuple[int, Unit, int], ...]   # (input index, driving unit, its output index)
    run: Callable[[], None]


def topo_schedule(system: System, context: Context, units: Sequence[Unit], out_nodes: set[tuple[str, int]],
                  skip_static: bool = False, held: Collection[str] = ()) -> list[Callable[[], None]]:
    """The Python ops of `schedule_steps` (same arguments)."""
    return [step.run for step in schedule_steps(system, context, units, out_nodes, skip_static, held)]


def schedule_steps(system: System, context: Context, units: Sequence[Unit], out_nodes: set[tuple[str, int]],
                   skip_static: bool = False, held: Collection[str] = ()) -> list[Step]:
    """Steps that set every input of `units` and evaluate the outputs in `out_nodes` (plus the
    outputs those inputs need) in dependency order, loops solved by LoopSolver.
    skip_static: leave out constant blocks and the inputs they drive (set once at the start;
    input values persist in every unit).
    held: blocks whose outputs are held between communication points (the co-simulation units of
    the mixed coupling): left out like constants, with the inputs they drive."""
    fixed = {name for name, u in system.units.items() if (skip_static and u.static) or name in held}
    src_of: dict[tuple[str, int], tuple[str, int]] = {}
    for u in units:
        for i in range(len(u.input_names)):
            sb, k = system.source_of(u, i)
            if sb in fixed:
                continue
            src_of[(u.name, i)] = (sb, k)
    out_nodes = {(b, k) for b, k in out_nodes if b not in fixed}
    need_out = set(out_nodes) | set(src_of.values())
    nodes: list[tuple[str, str, int]] = []
    edges: dict[tuple[str, str, int], list[tuple[str, str, int]]] = {}
    for (b, i) in src_of:
        nodes.append((b, "in", i))
        edges[(b, "in", i)] = []
    for (b, k) in sorted(need_out):
        nodes.append((b, "out", k))
        edges[(b, "out", k)] = []
    for (b, k) in sorted(need_out):
        for i in system.feedthrough[b][k]:
            if (b, "in", i) in edges:  # absent: an input driven by a constant (set once)
                edges[(b, "in", i)].append((b, "out", k))
    for (b, i), (sb, k) in src_of.items():
        edges[(sb, "out", k)].append((b, "in", i))
    sccs = strongly_connected(nodes, edges)
    comp_of = {}
    for ci, comp in enumerate(sccs):
        for n in comp:
            comp_of[n] = ci
    # condensed DAG, Kahn with a preference for staying on the same unit and op type
    succ: dict[int, set[int]] = {i: set() for i in range(len(sccs))}
    indeg = {i: 0 for i in range(len(sccs))}
    for v, ws in edges.items():
        for w in ws:
            a, b = comp_of[v], comp_of[w]
            if a != b and b not in succ[a]:
                succ[a].add(b)
                indeg[b] += 1
    ready = [i for i in indeg if indeg[i] == 0]
    order: list[int] = []
    last: tuple[str, str] | None = None
    pos = {n: idx for idx, n in enumerate(nodes)}
    while ready:
        def key(ci: int) -> tuple:
            comp = sccs[ci]
            n = comp[0]
            single = len(comp) == 1
            source = single and n[1] == "out" and not system.units[n[0]].input_names
            same = last is not None and single and (n[0], n[1]) == last
            # grouped by unit and direction to coalesce calls; sources first; then inputs (a
            # unit's inputs set before its outputs are read, so an FMU evaluates once)
            return (0 if same else 1, 0 if source else 1, 0 if single and n[1] == "in" else 1,
                    min(pos[m] for m in comp))
        ready.sort(key=key)
        ci = ready.pop(0)
        order.append(ci)
        comp = sccs[ci]
        last = (comp[0][0], comp[0][1]) if len(comp) == 1 else None
        for w in succ[ci]:
            indeg[w] -= 1
            if indeg[w] == 0:
                ready.append(w)
    ops: list[Step] = []
    pending: list[tuple[str, str, int]] = []

    def flush() -> None:
        if not pending:
            return
        b, kind, _ = pending[0]
        idx = [n[2] for n in pending]
        u = system.units[b]
        if kind == "in":
            ops.append(Step("set", u, tuple(idx), input_sources(system, u, idx, src_of),
                            setter_op(system, u, idx, src_of)))
        else:
            ops.append(Step("get", u, tuple(idx), (), u.output_getter(idx)))
        pending.clear()

    for ci in order:
        comp = sccs[ci]
        is_loop = len(comp) > 1 or comp[0] in edges.get(comp[0], [])
        if not is_loop:
            n = comp[0]
            if pending and (pending[0][0], pending[0][1]) != (n[0], n[1]):
                flush()
            pending.append(n)
            continue
        flush()
        ops.append(Step("loop", None, (), (), loop_op(system, context, comp, src_of, edges)))
    flush()
    return ops


def input_sources(system: System, u: Unit, idx: Sequence[int], src_of: dict) -> tuple[tuple[int, Unit, int], ...]:
    """(input index, driving unit, its output index) for inputs `idx` of u."""
    return tuple((i, system.units[src_of[(u.name, i)][0]], src_of[(u.name, i)][1]) for i in idx)


def setter_op(system: System, u: Unit, idx: list[int], src_of: dict) -> Callable[[], None]:
    """An op that copies the driving outputs into inputs `idx` of u and pushes them to its model."""
    sources = input_sources(system, u, idx, src_of)
    gathers = [(i, src.outbuf, k) for i, src, k in sources]
    raw_push = u.input_setter(idx)
    inbuf = u.inbuf

    def push() -> None:
        try:
            raw_push()
        except StepError as exc:
            raise non_finite_origin(u, sources, u.t) or exc from None

    if len(gathers) == 1:
        (i0, src0, k0), = gathers

        def op() -> None:
            inbuf[i0] = src0[k0]
            push()
        return op

    def op() -> None:
        for i, src, k in gathers:
            inbuf[i] = src[k]
        push()
    return op


def non_finite_origin(u: Unit, sources: Sequence[tuple[int, Unit, int]], t: float) -> StepError | None:
    """When a block refuses a NaN/inf input (featherstar's own FMUs do), the block that produced
    it is where the run failed, not the one that would not compute with it. `sources`: (input
    index of u, driving unit, its output index)."""
    for i, src, k in sources:
        value = u.inbuf[i]
        if not math.isfinite(value):
            return StepError(src.name, t, f"output {src.output_names[k]} = {value}",
                             cause=f"the block produced NaN/inf ({u.name}.{u.input_names[i]} refused it): its "
                             "model blew up, divided by zero, or got invalid parameters or inputs")
    return None


def loop_op(system: System, context: Context, comp: list, src_of: dict, edges: dict) -> LoopSolver:
    members = set(comp)
    tear = []
    setters, getters = [], []
    ins: dict[str, list[int]] = {}
    outs: dict[str, list[int]] = {}
    for b, kind, i in sorted(comp):
        (ins if kind == "in" else outs).setdefault(b, []).append(i)
    for b, idx in ins.items():
        u = system.units[b]
        for i in idx:
            sb, k = src_of[(b, i)]
            tear.append((u, i, system.units[sb], k))
        setters.append(u.input_setter(idx))
    for b, idx in outs.items():
        getters.append(system.units[b].output_getter(idx))
    # describe one cycle port by port
    cyc = cycle_through(comp[0], members, edges)

    def port_name(n: tuple[str, str, int]) -> str:
        u = system.units[n[0]]
        return f"{n[0]}.{(u.input_names if n[1] == 'in' else u.output_names)[n[2]]}"

    text = " -> ".join(port_name(n) for n in (*cyc, cyc[0]))
    master = system.master
    solver = LoopSolver(context, master.loop_tol, master.loop_max_iter, text, tear, setters, getters)
    context.loop_solvers.append(solver)
    return solver


def watched_out_nodes(system: System, recording: Recording) -> set[tuple[str, int]]:
    """The outputs evaluated at every recorded point: the recorded signals and what the guards read."""
    from ..scene.guards import watched_outputs

    out = watched_outputs(recording.guards)
    out.update(system.output_node(ref) for ref in recording.requested)
    return out
