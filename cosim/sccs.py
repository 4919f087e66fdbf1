"""Graph algorithms on port and block graphs: strongly connected components and one cycle
through a component (used by the scene checks, the guards and the schedule)."""
from __future__ import annotations

from typing import Any, Hashable, Iterable, Mapping, Sequence


def strongly_connected(nodes: Iterable[Hashable], edges: Mapping[Hashable, Sequence[Hashable]]) -> list[list[Any]]:
    """Strongly connected components (Tarjan, iterative), each a list of nodes; a component
    comes after every component it reaches."""
    index: dict = {}
    low: dict = {}
    on_stack: set = set()
    stack: list = []
    out: list = []
    counter = [0]

    def visit(v):
        # iterative Tarjan (scenes are small, but avoid recursion limits anyway)
        work = [(v, iter(edges[v]))]
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        while work:
            node, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(edges[w])))
                    advanced = True
                    break
                if w in on_stack:
                    low[node] = min(low[node], index[w])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == node:
                        break
                out.append(comp)

    for v in nodes:
        if v not in index:
            visit(v)
    return out


def cycle_through(start: Any, members: set, edges: Mapping[Hashable, Sequence[Hashable]]) -> list[Any]:
    """One cycle through `start` inside an SCC, starting at an output port for readability."""
    outs = [m for m in members if m[1] == "out"]
    if outs:
        start = sorted(outs)[0]
    prev = {start: None}
    queue = [start]
    found = None
    while queue and found is None:
        v = queue.pop(0)
        for w in edges[v]:
            if w == start:
                found = v
                break
            if w in members and w not in prev:
                prev[w] = v
                queue.append(w)
    path = []
    v = found
    while v is not None:
        path.append(v)
        v = prev[v]
    return list(reversed(path))
