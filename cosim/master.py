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

Runtime state lives in a RunContext made per run (this module); scenes and plans are never
modified. The schedule is `cosim.schedule`, the couplings `cosim.strong` and `cosim.weak`.
"""
from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from .errors import StepError
from .graph import Plan
from .guards import PassiveEnergyGuard, passive_energy_guards, watched_outputs
from .schedule import LoopSolver, flow_order
from .units import Unit


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
    late_steps: list[tuple[float, float]] = field(default_factory=list)  # realtime: (t, late_s)

    def loop_block(self, solver: LoopSolver) -> str:
        return ",".join(dict.fromkeys(u.name for u, _, _, _ in solver.tear))

    def record(self, t: float) -> None:
        """Record a checked point, then let the guards judge it (the point that trips one is kept)."""
        self.times.append(t)
        self.rows.append([buf[k] for buf, k in self.record_refs])
        for guard in self.guards:
            guard(t)

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


def watched_out_nodes(ctx: RunContext) -> set[tuple[str, int]]:
    """The outputs evaluated at every recorded point: the recorded signals and what the guards read."""
    out = watched_outputs(ctx.guards)
    for ref in ctx.plan.requested:
        c = ctx.plan.canonical(ref)
        out.add((c.block, ctx.units[c.block].output_names.index(c.port)))
    return out


def output_checker(ctx: RunContext, units: Sequence[Unit]) -> Callable[[float], None]:
    """A check that every unit's outputs are finite, in signal-flow order (the first bad one is
    the origin: downstream blocks only pass the NaN on)."""
    flow = [(u, u.outbuf, len(u.output_names)) for u in flow_order(ctx, units) if u.output_names]

    def check(t: float) -> None:
        for u, buf, n in flow:
            if not math.isfinite(sum(buf[:n])):
                for i in range(n):
                    if not math.isfinite(buf[i]):
                        raise StepError(u.name, t, f"output {u.output_names[i]} = {buf[i]}",
                                        cause="the block produced NaN/inf: its model blew up, divided by zero, "
                                        "or got invalid parameters or inputs")
    return check


def check_all_rows(ctx: RunContext) -> None:
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
