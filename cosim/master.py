"""The co-simulation master: strong and weak coupling over runtime units.

Strong coupling (`master.coupling = "strong"`): every unit with continuous states (Model Exchange
FMUs, in-process models) is integrated together as ONE ODE by CVODE (BDF for stiff scenes,
Adams otherwise), error-controlled on all states at once. Each right-hand-side evaluation sets
time and states on every unit and then walks a precomputed schedule: inputs are copied from
the outputs that drive them and outputs are evaluated in dependency order (direct feedthrough),
algebraic loops solved by Newton iteration on the loop's inputs. Memoryless blocks (the stroke
controller) are evaluated at the solver's own instants, so inputs are exact between
communication points — unlike fmpy's simulate_fmu, which holds them per output interval.
Outputs are recorded on the output grid from CVODE's dense output. State and time events of
generic ME FMUs are handled (root finding, event iteration, re-initialisation).

Weak coupling (`jacobi`, `gauss-seidel`): units are stepped as co-simulation units over macro
steps with inputs held (zero-order hold; FMI 3.0 co-simulation has no input derivatives).
Jacobi steps every unit from the values at t; Gauss–Seidel steps units in signal-flow order,
each from the newest values. After a macro step the schedule makes inputs and outputs
consistent at the new communication point (solving algebraic loops there). ME-only units are
stepped by their own CVODE. With `adaptive = true` the macro step is controlled by an error
estimate of the zero-order hold (half the change of each input over the step, relative to its
running magnitude, against `macro_rtol`): a step above tolerance is rolled back (saved FMU
states) and repeated smaller.

Runtime state lives in a RunContext made per run; scenes and plans are never modified.
"""
from __future__ import annotations

import ctypes
import math
import time
from ctypes import c_double
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from ._cvode import CVodeError, CVodeIntegrator
from .errors import StepError
from .graph import Plan, _tarjan
from .guards import PassiveEnergyGuard, passive_energy_guards, watched_outputs
from .scene import PortRef
from .units import Unit


# --------------------------------------------------------------------------------------------
# schedule: the order in which inputs are set and outputs evaluated at one instant
# --------------------------------------------------------------------------------------------

class LoopSolver:
    """Newton iteration (finite-difference Jacobian) on the inputs of an algebraic loop."""

    def __init__(self, ctx: "RunContext", description: str, tear: list[tuple[Unit, int, Unit, int]],
                 setters: list[Callable[[], None]], getters: list[Callable[[], None]]) -> None:
        self.ctx = ctx
        self.description = description
        self.tear = tear
        self.setters = setters
        self.getters = getters
        self.n = len(tear)
        self.v = np.array([u.inbuf[i] for u, i, _, _ in tear], dtype=float)
        self.iterations = 0
        self.solves = 0

    def _g(self, v: np.ndarray) -> np.ndarray:
        for j, (u, i, _, _) in enumerate(self.tear):
            u.inbuf[i] = v[j]
        for s in self.setters:
            s()
        for g in self.getters:
            g()
        return np.array([src.outbuf[k] for _, _, src, k in self.tear], dtype=float)

    def __call__(self) -> None:
        tol, max_iter = self.ctx.plan.scene.master.loop_tol, self.ctx.plan.scene.master.loop_max_iter
        v = self.v.copy()
        r = self._g(v) - v
        it = 0
        while True:
            scale = 1.0 + float(np.max(np.abs(v)))
            if not np.all(np.isfinite(r)):
                raise StepError(self.ctx.loop_block(self), self.ctx.t,
                                f"algebraic loop {self.description} produced NaN/inf",
                                cause="the loop diverged; its gain may exceed 1 or the blocks are invalid here")
            if float(np.max(np.abs(r))) <= tol * scale:
                break
            if it >= max_iter:
                raise StepError(self.ctx.loop_block(self), self.ctx.t,
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
                raise StepError(self.ctx.loop_block(self), self.ctx.t,
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


def _topo_schedule(ctx: "RunContext", units: Sequence[Unit], out_nodes: set[tuple[str, int]],
                   skip_static: bool = False) -> list[Callable[[], None]]:
    """Ops (closures) that set every input of `units` and evaluate the outputs in `out_nodes`
    (plus the outputs those inputs need) in dependency order, loops solved by LoopSolver.
    skip_static: leave out constant blocks and the inputs they drive (set once at the start;
    input values persist in every unit)."""
    plan = ctx.plan
    src_of: dict[tuple[str, int], tuple[str, int]] = {}
    for u in units:
        for i, name in enumerate(u.input_names):
            src = plan.driver(PortRef(u.name, name))
            su = ctx.units[src.block]
            if skip_static and su.static:
                continue
            src_of[(u.name, i)] = (su.name, su.output_names.index(src.port))
    if skip_static:
        out_nodes = {(b, k) for b, k in out_nodes if not ctx.units[b].static}
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
        for i in ctx.feedthrough[b][k]:
            if (b, "in", i) in edges:  # absent: an input driven by a constant (set once)
                edges[(b, "in", i)].append((b, "out", k))
    for (b, i), (sb, k) in src_of.items():
        edges[(sb, "out", k)].append((b, "in", i))
    sccs = _tarjan(nodes, edges)
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
            source = single and n[1] == "out" and not ctx.units[n[0]].input_names
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
    ops: list[Callable[[], None]] = []
    pending: list[tuple[str, str, int]] = []

    def flush() -> None:
        if not pending:
            return
        b, kind, _ = pending[0]
        idx = [n[2] for n in pending]
        u = ctx.units[b]
        if kind == "in":
            ops.append(_setter_op(ctx, u, idx, src_of))
        else:
            ops.append(u.output_getter(idx))
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
        ops.append(_loop_op(ctx, comp, src_of, edges))
    flush()
    return ops


def _setter_op(ctx: "RunContext", u: Unit, idx: list[int], src_of: dict) -> Callable[[], None]:
    gathers = []
    for i in idx:
        sb, k = src_of[(u.name, i)]
        gathers.append((i, ctx.units[sb].outbuf, k))
    push = u.input_setter(idx)
    inbuf = u.inbuf
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


def _loop_op(ctx: "RunContext", comp: list, src_of: dict, edges: dict) -> LoopSolver:
    members = set(comp)
    tear = []
    setters, getters = [], []
    ins: dict[str, list[int]] = {}
    outs: dict[str, list[int]] = {}
    for b, kind, i in sorted(comp):
        (ins if kind == "in" else outs).setdefault(b, []).append(i)
    for b, idx in ins.items():
        u = ctx.units[b]
        for i in idx:
            sb, k = src_of[(b, i)]
            tear.append((u, i, ctx.units[sb], k))
        setters.append(u.input_setter(idx))
    for b, idx in outs.items():
        getters.append(ctx.units[b].output_getter(idx))
    # describe one cycle port by port
    from .graph import _cycle

    cyc = _cycle(comp[0], members, edges)

    def port_name(n: tuple[str, str, int]) -> str:
        u = ctx.units[n[0]]
        return f"{n[0]}.{(u.input_names if n[1] == 'in' else u.output_names)[n[2]]}"

    text = " -> ".join(port_name(n) for n in (*cyc, cyc[0]))
    solver = LoopSolver(ctx, text, tear, setters, getters)
    ctx.loop_solvers.append(solver)
    return solver


# --------------------------------------------------------------------------------------------
# run context and recording
# --------------------------------------------------------------------------------------------

@dataclass
class RunContext:
    """Everything that changes during one run."""

    plan: Plan
    units: dict[str, Unit]
    feedthrough: dict[str, dict[int, list[int]]]  # unit -> output index -> input indices
    progress: Any = None
    t: float = 0.0
    times: list[float] = field(default_factory=list)
    rows: list[list[float]] = field(default_factory=list)
    record_refs: list[tuple[ctypes.Array, int]] = field(default_factory=list)
    loop_solvers: list[LoopSolver] = field(default_factory=list)
    stats: dict[str, Any] = field(default_factory=dict)
    guards: list[PassiveEnergyGuard] = field(default_factory=list)

    def loop_block(self, solver: LoopSolver) -> str:
        return ",".join(dict.fromkeys(u.name for u, _, _, _ in solver.tear))

    def record(self, t: float) -> None:
        row = [buf[k] for buf, k in self.record_refs]
        self.times.append(t)
        self.rows.append(row)

    def tick(self, t: float) -> None:
        if self.progress is not None:
            self.progress(t)


def make_context(plan: Plan, units: dict[str, Unit]) -> RunContext:
    feed: dict[str, dict[int, list[int]]] = {}
    for name, u in units.items():
        rb = plan.blocks[name]
        feed[name] = {}
        for k, out in enumerate(u.output_names):
            deps = rb.outputs[out].depends_on if out in rb.outputs else tuple(u.input_names)
            feed[name][k] = [u.input_names.index(d) for d in deps if d in u.input_names]
    ctx = RunContext(plan, units, feed)
    for ref in plan.requested:
        c = plan.canonical(ref)
        u = units[c.block]
        ctx.record_refs.append((u.outbuf, u.output_names.index(c.port)))
    # judged from one stroke period in (a tenth of the run without a stroke): see PassiveEnergyGuard
    ctx.guards = passive_energy_guards(units, plan.scene.master.passive_energy_factor,
                                       plan.period_s or 0.1 * plan.t_end_s)
    return ctx


def _requested_out_nodes(ctx: RunContext) -> set[tuple[str, int]]:
    """The outputs evaluated at every recorded point: the recorded signals and what the guards read."""
    out = watched_outputs(ctx.guards)
    for ref in ctx.plan.requested:
        c = ctx.plan.canonical(ref)
        out.add((c.block, ctx.units[c.block].output_names.index(c.port)))
    return out


def _output_checker(ctx: RunContext, units: Sequence[Unit]) -> Callable[[float], None]:
    """A check that every unit's outputs are finite, in signal-flow order (the first bad one is
    the origin: downstream blocks only pass the NaN on)."""
    flow = [(u, u.outbuf, len(u.output_names)) for u in _flow_order(ctx, units) if u.output_names]

    def check(t: float) -> None:
        for u, buf, n in flow:
            if not math.isfinite(sum(buf[:n])):
                for i in range(n):
                    if not math.isfinite(buf[i]):
                        raise StepError(u.name, t, f"output {u.output_names[i]} = {buf[i]}",
                                        cause="the block produced NaN/inf: its model blew up, divided by zero, "
                                        "or got invalid parameters or inputs")
    return check


def _record(ctx: RunContext, t: float) -> None:
    """Record a checked point, then let the guards judge it (the point that trips one is kept)."""
    ctx.record(t)
    for guard in ctx.guards:
        guard(t)


# --------------------------------------------------------------------------------------------
# strong coupling
# --------------------------------------------------------------------------------------------

class OdeGroup:
    """Units integrated together as one ODE by CVODE."""

    def __init__(self, ctx: RunContext, units: Sequence[Unit], rhs_ops: list[Callable[[], None]],
                 t0: float, *, method: str, rtol: float, atol: float, max_step: float = 0.0,
                 check_finite: bool = False) -> None:
        self.ctx = ctx
        self.units = list(units)
        self.timed = [u for u in units if u.continuous or u.memoryless]
        self.stateful: list[tuple[Unit, int]] = []
        off = 0
        for u in units:
            if u.continuous and u.n_states > 0:
                self.stateful.append((u, off))
                off += u.n_states
        self.n = max(off, 1)
        self.dummy = off == 0
        self.ops = rhs_ops
        self.event_units = [u for u in units if u.continuous and u.n_events > 0]
        self.n_events = sum(u.n_events for u in self.event_units)
        self.needs_completed = [u for u in units if u.continuous and u.needs_completed_step]
        self.check_finite = check_finite
        self._ydot_type = c_double * self.n
        x0 = self._initial_states()
        rhs = self._rhs if (check_finite or self.dummy) else self._specialised_rhs()
        lmm, _, nonlinear = method.partition("-")
        self.cv = CVodeIntegrator(self.n, rhs, t0, x0, method=lmm, nonlinear=nonlinear or "newton",
                                  rtol=rtol, atol=atol,
                                  max_step=max_step, n_roots=self.n_events,
                                  roots=self._roots if self.n_events else None)
        self.rhs_calls = 0

    def _initial_states(self) -> list[float]:
        x = (c_double * self.n)()
        for u, off in self.stateful:
            u.get_states(ctypes.addressof(x) + 8 * off)
        return list(x)

    def _rhs(self, t: float, y: int, yd: int) -> int:
        self.ctx.t = t
        for u in self.timed:
            u.set_time(t)
        for u, off in self.stateful:
            u.set_states(y + 8 * off)
        for op in self.ops:
            op()
        if self.dummy:
            self._ydot_type.from_address(yd)[0] = 0.0
            return 0
        for u, off in self.stateful:
            u.get_derivatives(yd + 8 * off)
        if self.check_finite and not math.isfinite(sum(self._ydot_type.from_address(yd))):
            return 1  # recoverable: CVODE retries with a smaller step, then fails if it persists
        # (off by default: a NaN derivative fails CVODE's error test anyway, and `diagnose`
        # then names the block and state; the check costs ~5 µs per call at 45 states)
        return 0

    def _specialised_rhs(self) -> Callable[[float, int, int], int]:
        """`_rhs` unrolled for this group: straight-line code with the raw FMI entry points
        bound as locals (saves the loops and attribute lookups, ~30 % of the Python overhead).
        On a bad status it calls the unit's normal method, which raises the StepError."""
        from .fmu_block import FmuUnit
        from .units import PyUnit

        env: dict[str, Any] = {"ctx": self.ctx}
        lines = ["def rhs(t, y, yd):", "    ctx.t = t"]
        for k, u in enumerate(self.timed):
            env[f"u{k}"] = u
            if isinstance(u, FmuUnit) and u.mode == "me":
                env[f"st{k}"], env[f"i{k}"] = u._set_time, u._inst
                lines += [f"    u{k}.t = t", f"    if st{k}(i{k}, t) > 1: u{k}.set_time(t)"]
            elif isinstance(u, PyUnit):
                lines.append(f"    u{k}.t = t")
            else:
                lines.append(f"    u{k}.set_time(t)")
        for k, (u, off) in enumerate(self.stateful):
            env[f"s{k}"] = u
            if isinstance(u, FmuUnit):
                env[f"sx{k}"], env[f"si{k}"] = u._set_x, u._inst
                lines.append(f"    if sx{k}(si{k}, y + {8 * off}, {u.n_states}) > 1: s{k}.set_states(y + {8 * off})")
            else:
                lines.append(f"    s{k}.set_states(y + {8 * off})")
        for j, op in enumerate(self.ops):
            env[f"op{j}"] = op
            lines.append(f"    op{j}()")
        for k, (u, off) in enumerate(self.stateful):
            if isinstance(u, FmuUnit):
                env[f"dx{k}"] = u._get_dx
                lines.append(f"    if dx{k}(si{k}, yd + {8 * off}, {u.n_states}) > 1: s{k}.get_derivatives(yd + {8 * off})")
            else:
                lines.append(f"    s{k}.get_derivatives(yd + {8 * off})")
        lines.append("    return 0")
        exec(compile("\n".join(lines), "<cosim rhs>", "exec"), env)
        return env["rhs"]

    def _roots(self, t: float, y: int, gout: int) -> int:
        self.set_point(t, y)
        off = 0
        for u in self.event_units:
            u.get_event_indicators(gout + 8 * off)
            off += u.n_events
        return 0

    def set_point(self, t: float, y_address: int) -> None:
        """Put every unit at (t, y) with consistent inputs and outputs."""
        self.ctx.t = t
        for u in self.timed:
            u.set_time(t)
        for u, off in self.stateful:
            u.set_states(y_address + 8 * off)
        for op in self.ops:
            op()

    def next_time_event(self) -> float:
        times = [u.next_time_event() for u in self.units if u.continuous]
        times = [t for t in times if t is not None]
        return min(times) if times else math.inf

    def handle_event(self, t: float) -> bool:
        """Event iteration at t on every event-capable unit; reinitialises CVODE. Returns terminate."""
        self.set_point(t, self.cv.y_address)
        changed_any, terminate = False, False
        for u in self.units:
            if u.continuous and (u.n_events or u.next_time_event() is not None or u.needs_completed_step):
                changed, _next, term = u.event_update()
                changed_any |= changed
                terminate |= term
        if changed_any:
            for u, off in self.stateful:
                u.get_states(self.cv.y_address + 8 * off)
        self.set_point(t, self.cv.y_address)
        self.cv.reinit(t)
        self.ctx.stats["events"] = self.ctx.stats.get("events", 0) + 1
        return terminate

    def integrate(self, t_end: float, out_times: np.ndarray, on_output: Callable[[float], None]) -> float:
        """Integrate to t_end, calling on_output(t) with every unit set at each output time."""
        cv = self.cv
        k = 0
        n_out = len(out_times)
        simple = not self.event_units and not self.needs_completed and self.next_time_event() == math.inf
        eps = 1e-12 * max(1.0, abs(t_end))
        while k < n_out and out_times[k] <= cv.t + eps:
            self.set_point(out_times[k], cv.y_address)
            on_output(out_times[k])
            k += 1
        if simple:
            cv.set_stop_time(t_end)
            while k < n_out:
                tout = min(out_times[k], t_end)
                cv.advance(tout)
                self.set_point(tout, cv.y_address)
                on_output(tout)
                k += 1
            if cv.t < t_end - eps:
                cv.advance(t_end)
            self.set_point(cv.t, cv.y_address)
            return cv.t
        while cv.t < t_end - eps:
            t_stop = min(t_end, self.next_time_event())
            cv.set_stop_time(t_stop)
            flag = cv.advance(t_stop, one_step=True)
            t_cur = cv.t
            while k < n_out and out_times[k] <= t_cur + eps:
                y = cv.interpolate(min(out_times[k], t_cur))
                self.set_point(out_times[k], ctypes.addressof(y))
                on_output(out_times[k])
                k += 1
            event = flag == 2 or (flag == 1 and t_stop < t_end and abs(t_cur - t_stop) <= eps)
            if self.needs_completed and not event:
                self.set_point(t_cur, cv.y_address)
                for u in self.needs_completed:
                    enter, term = u.completed_integrator_step()
                    event |= enter
                    if term:
                        return t_cur
            if event and self.handle_event(t_cur):
                return t_cur
        self.set_point(cv.t, cv.y_address)
        return cv.t

    def diagnose(self, exc: CVodeError) -> StepError:
        """Why did CVODE fail? Look at every unit at the last successful state, and at the time
        where the solver gave up: the first non-finite output in signal-flow order is the origin."""
        t_good = self.cv.t
        cause = str(exc)
        t_fail = _time_in(self.cv.last_error, t_good)
        y = list(self.cv.y)
        ydot = (c_double * self.n)()
        flow = [u for u in _flow_order(self.ctx, self.ctx.units.values()) if u in self.units]
        probes = [t_good, t_fail] + [t_fail + d * max(1.0, abs(t_fail)) for d in (1e-12, 1e-10, 1e-8, 1e-6, 1e-4)]
        for t in probes:
            try:
                self.set_point(t, self.cv.y_address)
            except StepError as inner:
                return inner
            for u in flow:
                for i in range(len(u.output_names)):
                    if not math.isfinite(u.outbuf[i]):
                        return StepError(u.name, t, f"output {u.output_names[i]} = {u.outbuf[i]}",
                                         function="CVODE", cause="the block produced NaN/inf (division by zero, "
                                         "invalid parameters or inputs out of range); the solver then failed: " + cause)
            worst: tuple[float, str, str] | None = None
            for u, off in self.stateful:
                names = u.state_names() or [f"x{i}" for i in range(u.n_states)]
                try:
                    u.get_derivatives(ctypes.addressof(ydot) + 8 * off)
                except StepError as inner:
                    return inner
                for i in range(u.n_states):
                    xi, di = y[off + i], ydot[off + i]
                    if not (math.isfinite(xi) and math.isfinite(di)):
                        return StepError(u.name, t, f"state {names[i]} = {xi}, derivative {di}: NaN/inf",
                                         function="CVODE", cause="the model divided by zero or left its valid range")
                    size = abs(di) / (1.0 + abs(xi))
                    if worst is None or size > worst[0]:
                        worst = (size, u.name, names[i])
        if worst is not None:
            block, state = worst[1], worst[2]
            return StepError(block, t_good, f"the solver failed: {cause}", function="CVODE",
                             cause=f"fastest-changing state is {block}.{state} (|dx/dt|/(1+|x|) = {worst[0]:.3g}): "
                             "a blow-up or a very stiff transient in that block; check its parameters, or try master.method = bdf")
        return StepError(self.units[0].name if self.units else "master", t_good, f"the solver failed: {cause}",
                         function="CVODE")


def _time_in(message: str, default: float) -> float:
    import re

    match = re.search(r"t\s*=\s*([-+0-9.eE]+)", message or "")
    try:
        return float(match.group(1)) if match else default
    except ValueError:
        return default


def run_strong(ctx: RunContext, t0: float, t_end: float) -> None:
    plan = ctx.plan
    m = plan.scene.master
    units = list(ctx.units.values())
    rhs_ops = _topo_schedule(ctx, units, set(), skip_static=True)
    rec_ops = _topo_schedule(ctx, units, _requested_out_nodes(ctx), skip_static=True)
    init_ops = _topo_schedule(ctx, units, _requested_out_nodes(ctx))
    group = OdeGroup(ctx, units, rhs_ops, t0, method=m.method, rtol=m.rtol, atol=m.atol, max_step=m.max_step_s)
    group.ops = init_ops  # initial point: everything, constants included, consistent
    group.set_point(t0, group.cv.y_address)
    group.ops = rhs_ops
    n = int(math.floor((t_end - t0) / m.output_interval_s + 1e-9))
    out_times = t0 + m.output_interval_s * np.arange(n + 1)
    if out_times[-1] < t_end - 1e-12:
        out_times = np.append(out_times, t_end)

    check = _output_checker(ctx, units)

    def on_output(t: float) -> None:
        for op in rec_ops:
            op()
        check(t)
        _record(ctx, t)
        if len(ctx.rows) % 256 == 0:
            ctx.tick(t)

    t_wall = time.perf_counter()
    try:
        group.integrate(t_end, out_times, on_output)
    except CVodeError as exc:
        raise group.diagnose(exc) from None
    finally:
        ctx.stats.update(group.cv.stats())
        ctx.stats["integrate_s"] = time.perf_counter() - t_wall
        ctx.stats["states"] = 0 if group.dummy else group.n
    _check_all_rows(ctx)


def _check_all_rows(ctx: RunContext) -> None:
    if not ctx.rows:
        return
    arr = np.asarray(ctx.rows, dtype=float)
    bad = ~np.isfinite(arr)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        ref = ctx.plan.canonical(ctx.plan.requested[c])
        t = ctx.times[r]
        del ctx.times[r:], ctx.rows[r:]
        raise StepError(ref.block, t, f"output {ref.port} is {arr[r, c]}",
                        cause="the block's model blew up or divided by zero; check its parameters and inputs")


# --------------------------------------------------------------------------------------------
# weak coupling
# --------------------------------------------------------------------------------------------

class MeStepper:
    """Steps one Model Exchange unit as a co-simulation unit with its own CVODE (inputs held)."""

    def __init__(self, ctx: RunContext, unit: Unit, t0: float, method: str, rtol: float, atol: float) -> None:
        self.unit = unit
        self.group = OdeGroup(ctx, [unit], [], t0, method=method, rtol=rtol, atol=atol)

    def do_step(self, t: float, h: float) -> None:
        g = self.group
        g.cv.reinit(t)  # the inputs jumped at the communication point
        try:
            g.integrate(t + h, np.empty(0), lambda _t: None)
        except CVodeError as exc:
            raise g.diagnose(exc) from None
        self.unit.set_time(t + h)
        if g.stateful:
            self.unit.set_states(g.cv.y_address)

    def get_state(self) -> Any:
        return (self.group.cv.t, list(self.group.cv.y), self.unit.get_state())

    def set_state(self, state: Any) -> None:
        t, y, inner = state
        self.unit.set_state(inner)
        for i, v in enumerate(y):
            self.group.cv.y[i] = v
        self.group.cv.t = t
        if self.group.stateful:
            self.unit.set_time(t)
            self.unit.set_states(self.group.cv.y_address)

    def free_state(self, state: Any) -> None:
        self.unit.free_state(state[2])


def run_weak(ctx: RunContext, t0: float, t_end: float) -> None:
    plan = ctx.plan
    m = plan.scene.master
    units = list(ctx.units.values())
    steppers: dict[str, Any] = {}
    for u in units:
        if u.memoryless:
            continue
        steppers[u.name] = MeStepper(ctx, u, t0, m.method, m.rtol, m.atol) if u.continuous else u
    sched = _topo_schedule(ctx, units, _requested_out_nodes(ctx))
    # Gauss–Seidel order: signal flow, sources first
    flow = _flow_order(ctx, units)
    per_unit_set = {u.name: _setter_op(ctx, u, list(range(len(u.input_names))), _sources(ctx, u))
                    for u in units if u.input_names}
    per_unit_get = {u.name: u.output_getter(list(range(len(u.output_names)))) for u in units if u.output_names}
    stepped = [u for u in flow if u.name in steppers]
    memoryless = [u for u in units if u.memoryless]

    def consistent(t: float) -> None:
        ctx.t = t
        for u in memoryless:
            u.set_time(t)
        for op in sched:
            op()

    check = _output_checker(ctx, units)
    consistent(t0)
    check(t0)
    _record(ctx, t0)
    h = m.step_s
    t = t0
    scale = {u.name: [abs(u.inbuf[i]) for i in range(len(u.input_names))] for u in stepped}
    n_steps = n_rejected = 0
    eps = 1e-12 * max(1.0, abs(t_end))
    gs = m.coupling == "gauss-seidel"
    wall_start = time.perf_counter()
    misses, worst_lateness = 0, 0.0
    while t < t_end - eps:
        if m.realtime:
            # Hardware in the loop: a step may not start before its wall-clock time; one that
            # starts more than a step late missed its deadline (the device saw a stale command).
            lateness = time.perf_counter() - wall_start - (t - t0)
            if lateness < 0:
                time.sleep(-lateness)
            elif lateness > h:
                misses += 1
            worst_lateness = max(worst_lateness, lateness)
        h_try = min(h, t_end - t)
        if t + h_try > t_end - 1e-9 * h_try:
            h_try = t_end - t
        saved = {n: s.get_state() for n, s in steppers.items()} if m.adaptive else None
        used: dict[str, list[float]] = {}
        try:
            if gs:
                for u in flow:
                    if u.memoryless:
                        ctx.t = t + h_try
                        u.set_time(t + h_try)
                        if u.name in per_unit_set:
                            per_unit_set[u.name]()
                        if u.name in per_unit_get:
                            per_unit_get[u.name]()
                        continue
                    ctx.t = t
                    if u.name in per_unit_set:
                        per_unit_set[u.name]()
                    used[u.name] = list(u.inbuf)[: len(u.input_names)]
                    steppers[u.name].do_step(t, h_try)
                    if u.name in per_unit_get:
                        per_unit_get[u.name]()
            else:
                for u in stepped:
                    used[u.name] = list(u.inbuf)[: len(u.input_names)]
                ctx.t = t
                for u in stepped:
                    steppers[u.name].do_step(t, h_try)
            consistent(t + h_try)
        except StepError as exc:
            if m.adaptive and saved is not None and h_try > m.min_step_s and "discard" in str(exc):
                for n, s in steppers.items():
                    s.set_state(saved[n])
                consistent(t)
                h = h_try * 0.25
                n_rejected += 1
                continue
            raise
        if m.adaptive:
            err = 0.0
            for u in stepped:
                sc = scale[u.name]
                for i, old in enumerate(used[u.name]):
                    new = u.inbuf[i]
                    sc[i] = max(sc[i], abs(new))
                    e = 0.5 * abs(new - old) / (m.atol + m.macro_rtol * sc[i])
                    if e > err:
                        err = e
            if err > 1.0 and h_try > m.min_step_s * 1.0001:
                for n, s in steppers.items():
                    s.set_state(saved[n])
                    s.free_state(saved[n])
                consistent(t)
                h = max(m.min_step_s, h_try * max(0.2, 0.9 / err))
                n_rejected += 1
                continue
            for n, s in steppers.items():
                s.free_state(saved[n])
            h = min(m.max_macro_step_s, h_try * min(2.0, 0.9 / max(err, 1e-12)))
        t = t + h_try
        n_steps += 1
        check(t)
        _record(ctx, t)
        if n_steps % 256 == 0:
            ctx.tick(t)
    ctx.stats.update({"macro_steps": n_steps, "rejected_steps": n_rejected})
    if m.realtime:
        ctx.stats.update({"deadline_misses": misses, "worst_lateness_s": worst_lateness})
    _check_all_rows(ctx)


def _sources(ctx: RunContext, u: Unit) -> dict[tuple[str, int], tuple[str, int]]:
    out = {}
    for i, name in enumerate(u.input_names):
        src = ctx.plan.driver(PortRef(u.name, name))
        out[(u.name, i)] = (src.block, ctx.units[src.block].output_names.index(src.port))
    return out


def _flow_order(ctx: RunContext, units: Sequence[Unit]) -> list[Unit]:
    """Units in signal-flow order (sources first); feedback edges broken at the latest unit."""
    names = [u.name for u in units]
    preds = {n: set() for n in names}
    for u in units:
        for name in u.input_names:
            src = ctx.plan.driver(PortRef(u.name, name)).block
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
    return [ctx.units[n] for n in order]
