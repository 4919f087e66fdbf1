"""Build-time analysis of a scene: validation, pruning, deduplication and algebraic loops.

`plan(scene, outputs)` resolves every block (no FMU binary is loaded), checks the wiring and
collects *all* problems into one SceneError: unknown blocks and ports, outputs used as inputs,
dangling and doubly driven inputs, unit mismatches, signals that do not exist, algebraic loops
that cannot be iterated (printed port by port), couplings a block cannot take part in.

Units: FMI makes a variable's unit optional, so a port without one (`""`) connects to anything
and the plan notes the connection as unchecked; two declared units must be equal (`"1"` and `"-"`
are both dimensionless) unless the scene waives that connection (`[units] waive`).

It then decides what the run needs:
* pruning: only blocks that feed a requested signal (recorders' signals and the metrics'
  signals, or the caller's `outputs`) are instantiated; only requested signals are recorded;
* deduplication: blocks with the same identity (same model, options and parameters) whose
  inputs are driven by the same signals compute the same trajectory; one representative is
  integrated and the others' outputs alias its outputs (the robot's two feathers);
* algebraic loops: strongly connected components of the port graph (connections plus each
  block's direct feedthrough), each with one cycle spelled out for messages.
"""
from __future__ import annotations

import dataclasses

from typing import Iterable, Sequence

from ..errors import SceneError
from ..fmi.fmi_types import conversion_problem
from ..sccs import cycle_through, strongly_connected
from .block_kind import ResolvedBlock
from .blocks import KINDS, resolve
from .data import FrozenMap, PortRef, Scene
from .specs import Connection
from .fmu_ports import expand_array_connections, expand_array_refs, hold_unconnected_inputs, keep_used_outputs
from .guards import step_problems
from .plan import Loop, Plan
from .settings import close_match

DIMENSIONLESS = {"1", "-"}


def same_unit(a: str, b: str) -> bool:
    """Two declared units name the same unit (no conversion: "mm" is not "m")."""
    a, b = a.strip(), b.strip()
    return a == b or (a in DIMENSIONLESS and b in DIMENSIONLESS)


def declares_unit(unit: str) -> bool:
    """FMI leaves a variable's unit optional: "" means none was declared (not dimensionless)."""
    return bool(unit.strip())


def _unit_checks(connections: Sequence[Connection], waived: set[Connection],
                 resolved: dict[str, ResolvedBlock]) -> tuple[list[str], list[str]]:
    """(problems, notes) of the unit check over connections whose ports exist."""
    problems, unchecked, waived_used = [], [], []
    for conn in connections:
        u_src = resolved[conn.src.block].outputs[conn.src.port].unit
        u_dst = resolved[conn.dst.block].inputs[conn.dst.port].unit
        if not (declares_unit(u_src) and declares_unit(u_dst)):
            unchecked.append(str(conn))
        elif same_unit(u_src, u_dst):
            continue
        elif conn in waived:
            waived_used.append(f"{conn} ('{u_src}' into '{u_dst}')")
        else:
            problems.append(f"unit mismatch on '{conn}': output is in '{u_src}', input expects '{u_dst}' "
                            f"(if the values agree, waive it: [units] waive = [\"{conn}\"])")
    notes = []
    if unchecked:
        notes.append(f"units not checked (a port declares no unit): {', '.join(unchecked)}")
    if waived_used:
        notes.append(f"unit check waived by the scene ([units] waive): {', '.join(waived_used)}")
    return problems, notes


def _port_list(ports: Iterable[str]) -> str:
    return ", ".join(ports) or "none"


def _share_parameters(resolved: dict[str, ResolvedBlock]) -> list[str]:
    """Give every model block that has a parameter some block shares (`shared_parameters`, e.g.
    the stroke's amplitude) and leaves it unset the shared value, when the scene's blocks agree on
    one; returns the plan notes saying so."""
    offers: dict[str, dict[float, str]] = {}
    for name, rb in resolved.items():
        for key, value in rb.shared_parameters.items():
            offers.setdefault(key, {}).setdefault(float(value), name)
    notes = []
    for key, values in offers.items():
        if len(values) != 1:
            continue
        (value, source), = values.items()
        followers = []
        for name, rb in resolved.items():
            if rb.model is None or key in rb.parameters or key not in {p.name for p in rb.model.parameters}:
                continue
            rb.parameters[key] = value
            kind, model_ref, options, _ = rb.identity
            rb.identity = (kind, model_ref, options, FrozenMap(rb.parameters))
            followers.append(name)
        if followers:
            notes.append(f"{', '.join(followers)}: {key} = {value:.4g} follows block '{source}'")
    return notes


def plan(scene: Scene, outputs: Sequence[str] | None = None) -> Plan:
    problems: list[str] = []
    resolved: dict[str, ResolvedBlock] = {}
    names = scene.block_names
    for dup in sorted({n for n in names if names.count(n) > 1}):
        problems.append(f"block name '{dup}' is used twice")
    for spec in scene.blocks:
        if spec.kind not in KINDS:
            problems.append(f"block '{spec.name}': unknown block kind '{spec.kind}'{close_match(spec.kind, KINDS)} "
                            f"(known kinds: {', '.join(KINDS)})")
            continue
        try:
            resolved[spec.name] = resolve(spec)
        except SceneError as exc:
            problems.extend(exc.problems)
        except (TypeError, ValueError, ArithmeticError) as exc:   # a kind meeting data it cannot read
            problems.append(f"block '{spec.name}' ({spec.kind}): a setting it cannot read: {exc}")
    amplitude_notes = _share_parameters(resolved)
    known = ", ".join(names)

    def check_output(ref: PortRef, what: str) -> bool:
        if ref.block not in names:
            problems.append(f"{what}: unknown block '{ref.block}'; blocks are: {known}")
            return False
        rb = resolved.get(ref.block)
        if rb is None:
            return False
        if ref.port not in rb.outputs:
            extra = " (that is an input)" if ref.port in rb.inputs else ""
            problems.append(f"{what}: block '{ref.block}' has no output '{ref.port}'{extra}; "
                            f"its outputs: {_port_list(rb.outputs)}")
            return False
        return True

    source_of: dict[PortRef, PortRef] = {}
    checked: list[Connection] = []
    for conn in expand_array_connections(scene.connections, resolved, problems):
        ok = check_output(conn.src, f"connection '{conn}'")
        dst = conn.dst
        if dst.block not in names:
            problems.append(f"connection '{conn}': unknown block '{dst.block}'; blocks are: {known}")
            continue
        rb = resolved.get(dst.block)
        if rb is None:
            continue
        if dst.port not in rb.inputs:
            extra = " (that is an output)" if dst.port in rb.outputs else ""
            problems.append(f"connection '{conn}': block '{dst.block}' has no input '{dst.port}'{extra}; "
                            f"its inputs: {_port_list(rb.inputs)}")
            continue
        if dst in source_of:
            problems.append(f"input {dst} is driven twice: by {source_of[dst]} and by {conn.src}")
            continue
        source_of[dst] = conn.src
        if ok:
            checked.append(conn)
            why = conversion_problem(resolved[conn.src.block].outputs[conn.src.port].type, rb.inputs[dst.port].type)
            if why:
                problems.append(f"type mismatch on '{conn}': {why}")
    waived = set(expand_array_connections(scene.unit_waivers, resolved, problems))
    for conn in sorted(waived - set(checked), key=str):
        problems.append(f"[units] waive: '{conn}' is not a connection of the scene")
    unit_problems, unit_notes = _unit_checks(checked, waived, resolved)
    problems.extend(unit_problems)
    held_notes: list[str] = []
    for name, rb in resolved.items():
        dangling = [port for port in rb.inputs if PortRef(name, port) not in source_of]
        if dangling and rb.fmu_info is not None and rb.model is None:
            held_notes.append(f"{name}: input(s) {', '.join(dangling)} not connected: held at the FMU's start values")
            hold_unconnected_inputs(rb, set(dangling))
            continue
        for port in dangling:
            problems.append(f"input {PortRef(name, port)} is not connected (dangling): connect an output to it "
                            f"(a constant block for a fixed value)")

    # requested signals
    requested: list[PortRef] = []
    if outputs is not None:
        for text in outputs:
            try:
                requested.append(PortRef.parse(text, "requested output"))
            except SceneError as exc:
                problems.extend(exc.problems)
    else:
        for rb in resolved.values():
            requested.extend(rb.signals)
    requested = expand_array_refs(requested, resolved)
    metric_refs = []
    for ref in requested:
        check_output(ref, f"signal {ref}")
    for attr in ("thrust", "angle", "speed", "position"):
        text = getattr(scene.metrics, attr)
        if text:
            try:
                metric_refs.append(PortRef.parse(text, f"metrics.{attr}"))
            except SceneError as exc:
                problems.extend(exc.problems)
                continue
            check_output(metric_refs[-1], f"metrics.{attr} = '{text}'")
    record_all_notes = []
    if outputs is None and not requested and not metric_refs:
        # A system from elsewhere (an SSP package without system outputs) names nothing to record:
        # pruning would leave nothing to compute, so every block's every output is recorded.
        requested = [PortRef(n, port) for n, rb in resolved.items() if not rb.records_only for port in rb.outputs]
        if requested:
            record_all_notes.append(f"no signals requested (no recorder, metrics or --record): recording every "
                                    f"output of every block ({len(requested)} signals)")
    problems.extend(scene.master.check())
    problems.extend(scene.metrics.check())
    if problems:
        raise SceneError(problems, scene.name)
    for ref in metric_refs:
        if ref not in requested:
            requested.append(ref)
    requested = list(dict.fromkeys(requested))

    # pruning: blocks upstream of the requested signals
    needed: set[str] = set()
    stack = [r.block for r in requested]
    while stack:
        b = stack.pop()
        if b in needed:
            continue
        needed.add(b)
        for port in resolved[b].inputs:
            stack.append(source_of[PortRef(b, port)].block)
    # a needed periodic source (the stroke controller) gives the period even if nothing records it
    strokes = [n for n, rb in resolved.items() if rb.gives_period]
    period = scene.metrics.period_s or None
    if period is None:
        periods = [resolved[n].period_s for n in strokes if n in needed] or [resolved[n].period_s for n in strokes]
        period = periods[0] if periods else None
    pruned = [n for n in names if n not in needed and not resolved[n].records_only]

    # deduplication
    alias_of = {n: n for n in needed}
    if scene.master.dedup:
        changed = True
        while changed:
            changed = False
            groups: dict[object, str] = {}
            for n in names:
                if n not in needed or alias_of[n] != n:
                    continue
                rb = resolved[n]
                if rb.identity is None:
                    continue
                drive = tuple(sorted(
                    (port, alias_of[source_of[PortRef(n, port)].block], source_of[PortRef(n, port)].port)
                    for port in rb.inputs))
                key = (rb.identity, drive)
                if key in groups:
                    alias_of[n] = groups[key]
                    changed = True
                else:
                    groups[key] = n
            # chase chains
            for n in alias_of:
                while alias_of[alias_of[n]] != alias_of[n]:
                    alias_of[n] = alias_of[alias_of[n]]
    instantiate = [n for n in names if n in needed and alias_of[n] == n]
    notes: list[str] = list(amplitude_notes) + record_all_notes + unit_notes + held_notes
    for n in names:
        if n in needed and alias_of[n] != n:
            notes.append(f"'{n}' is identical to '{alias_of[n]}' and driven by the same signals: integrated once")
    if pruned:
        notes.append(f"not needed for the requested signals, not instantiated: {', '.join(pruned)}")

    scene, coupling_note = _resolve_auto_coupling(scene, [resolved[n] for n in instantiate])
    notes += coupling_note
    p = Plan(scene, resolved, instantiate, alias_of, source_of, requested, [], period, 0.0, pruned, notes)
    keep_used_outputs(p)
    p.loops = find_loops(p)
    problems = []
    for loop in p.loops:
        stuck = [b for b in loop.blocks if not resolved[b].iterable]
        if scene.master.algebraic_loops == "error":
            problems.append(f"algebraic loop {loop.describe()}: master.algebraic_loops = 'error'")
        elif stuck:
            problems.append(
                f"algebraic loop {loop.describe()} cannot be solved: block(s) {', '.join(stuck)} cannot be "
                "re-evaluated for trial inputs (hardware or a block without can_iterate); break the loop "
                "with a block whose output does not depend directly on its input (a filter or a delay)")
    problems.extend(_check_coupling(p))
    if scene.master.coupling == "mixed" and scene.master.adaptive:
        problems.append("master.adaptive controls the macro step of jacobi and gauss-seidel; the mixed coupling "
                        "steps at master.step_s (set master.adaptive = false)")
    problems.extend(step_problems(p))
    master = scene.master
    if master.t_end_s > 0:
        p.t_end_s = master.t_end_s
    elif period:
        p.t_end_s = master.periods * period
    else:
        problems.append("master: no stroke controller gives a period; set master.t_end_s")
    if problems:
        raise SceneError(problems, scene.name)
    return p


def _resolve_auto_coupling(scene: Scene, blocks: Sequence[ResolvedBlock]) -> tuple[Scene, list[str]]:
    """master.coupling = auto: strong when every block can join one ODE, mixed when some can and
    some can only step (co-simulation-only FMUs, Python blocks with state), gauss-seidel when none
    has continuous states; the scene then carries the chosen coupling, and a note says it."""
    if scene.master.coupling != "auto":
        return scene, []
    computing = [rb for rb in blocks if not rb.records_only]
    ode = [rb.name for rb in computing if rb.continuous]
    stepped = [rb.name for rb in computing if not rb.continuous and not rb.memoryless]
    if not stepped:
        chosen, why = "strong", "every block joins one ODE"
    elif ode:
        chosen, why = "mixed", f"{', '.join(stepped)} only step{'s' if len(stepped) == 1 else ''}"
    else:
        chosen, why = "gauss-seidel", "no block has continuous states"
    master = dataclasses.replace(scene.master, coupling=chosen)
    return dataclasses.replace(scene, master=master), [f"master.coupling = auto: {chosen} ({why})"]


def _check_coupling(p: Plan) -> list[str]:
    master = p.scene.master
    problems = []
    for n in p.instantiate:
        rb = p.blocks[n]
        if master.coupling == "strong" and not rb.continuous:
            why = ("a co-simulation-only FMU" if rb.fmu_info is not None else "a Python block with state")
            problems.append(f"block '{n}' is {why}: it cannot be integrated in one ODE with the others "
                            "(master.coupling = strong); use master.coupling = mixed (the others stay one ODE), "
                            "jacobi or gauss-seidel")
        if rb.fmu_info is not None and not (rb.fmu_info.has_me or rb.fmu_info.has_cs):
            problems.append(f"block '{n}': the FMU offers neither <ModelExchange> nor <CoSimulation> "
                            "(FMI 3.0 <ScheduledExecution> is not supported)")
        if master.coupling in ("jacobi", "gauss-seidel") and master.adaptive and not rb.can_rollback:
            problems.append(f"block '{n}' cannot save and restore its state, which the adaptive macro step "
                            "needs to reject a step; set master.adaptive = false")
    return problems


def find_loops(p: Plan) -> list[Loop]:
    """Algebraic loops among the instantiated blocks: SCCs of the port graph."""
    nodes: list[tuple[str, str, str]] = []  # (block, "in"/"out", port)
    edges: dict[tuple[str, str, str], list[tuple[str, str, str]]] = {}
    for n in p.instantiate:
        rb = p.blocks[n]
        for port in rb.inputs:
            node = (n, "in", port)
            nodes.append(node)
            edges.setdefault(node, [])
        for port, spec in rb.outputs.items():
            node = (n, "out", port)
            nodes.append(node)
            edges.setdefault(node, [])
            for dep in spec.depends_on:
                edges[(n, "in", dep)].append(node)
    for n in p.instantiate:
        for port in p.blocks[n].inputs:
            src = p.driver(PortRef(n, port))
            edges[(src.block, "out", src.port)].append((n, "in", port))
    sccs = strongly_connected(nodes, edges)
    loops = []
    for comp in sccs:
        members = set(comp)
        if len(comp) == 1 and comp[0] not in edges[comp[0]]:
            continue
        cycle = cycle_through(comp[0], members, edges)
        blocks = tuple(dict.fromkeys(b for b, _, _ in sorted(comp)))
        loops.append(Loop(
            blocks=blocks,
            inputs=tuple(PortRef(b, q) for b, d, q in sorted(comp) if d == "in"),
            outputs=tuple(PortRef(b, q) for b, d, q in sorted(comp) if d == "out"),
            cycle=tuple(PortRef(b, q) for b, d, q in cycle),
        ))
    return loops
