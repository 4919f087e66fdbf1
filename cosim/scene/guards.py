"""Guards: runs whose numbers could not be trusted stop with a clear error instead.

Two kinds, both measured rather than guessed (docs/stability.md has the tables):

* **Before the run** (`step_problems`, part of the scene check, SceneError): a recording grid or a
  fixed weak-coupling macro step too coarse for the stroke, and a macro step too long for the
  fastest time constant on a feedback loop between weakly coupled blocks. Past these limits the
  master used to return plausible-looking but wrong numbers (test bed, Jacobi at 10 ms: TR 1.6
  instead of 0.985; a 0.5 s recording grid: TR 0.03).
* **During the run** (`passive_energy_guards`, StepError): a passive block, one that water and
  damping can only take energy out of, may not hold much more mechanical energy than its ports
  have put in. This catches a coupling loop or a block's model that creates energy, which would
  otherwise finish with joules of energy and absurd thrust ratios (the feather's Morison
  added-mass force did, before issue 11 made it energy-consistent; docs/stability.md).

`master.check_steps = false` lifts the first kind (to study the coupling error itself, as
bench/stability_map.py does); `master.passive_energy_factor = 0` the second.
"""
from __future__ import annotations

from typing import Mapping, Sequence

from ..errors import StepError
from ..framework.block import Passivity
from ..framework.units import Unit
from ..sccs import strongly_connected
from .plan import Plan

#: Samples of the stroke's shortest ramp the recording grid (and a fixed macro step) must give.
#: At the paper's 0.25 s ramps, a 10 ms grid keeps the chordwise TR within 2.5 % of the 1 ms one
#: (thrust has sharp flap-impact peaks); 25 ms is 11 % off, 100 ms 50 % (bench/guard_margins.py).
SAMPLES_PER_RAMP = 25
#: Largest weak-coupling macro step on a feedback loop, in units of the loop's fastest time
#: constant. Set when the test bed (servo load filter 5 ms) went unstable from 7-15 ms under
#: Jacobi and 10-30 ms under Gauss-Seidel with the Morison feather; the energy-consistent feather
#: stays bounded to 30-50 ms and beyond but is inaccurate past these steps (docs/stability.md).
LOOP_STEP_PER_TIME_CONSTANT = {"jacobi": 1.0, "gauss-seidel": 2.0, "mixed": 1.0}
#: Gains below this are not judged (the feathers here hold 0.01-0.07 J).
ENERGY_FLOOR_J = 1e-6


def _shortest_ramp(plan: "Plan") -> tuple[float, str] | None:
    ramps = []
    for name in plan.instantiate:
        rb = plan.blocks[name]
        ramps += list(rb.ramps_s)
    return min(ramps) if ramps else None


def feedback_loops(plan: "Plan") -> list[list[str]]:
    """Groups of instantiated blocks that feed each other (strongly connected, through any port)."""
    edges: dict[str, list[str]] = {n: [] for n in plan.instantiate}
    for dst, src in plan.source_of.items():
        a, b = plan.canonical(src).block, plan.canonical(dst).block
        if a in edges and b in edges and a != b:
            edges[a].append(b)
    return [sorted(c) for c in strongly_connected(list(edges), edges) if len(c) > 1]


def _fastest_time_constant(plan: "Plan", blocks: Sequence[str]) -> tuple[float, str] | None:
    """The smallest `*time_constant_s` parameter of the blocks: a model's defaults with the scene's
    values over them (an FMU file's defaults are not known before it is loaded; its set values are)."""
    found = []
    for b in blocks:
        rb = plan.blocks[b]
        values = rb.model.default_parameters() if rb.model is not None else {}
        values.update(rb.parameters)
        found += [(v, f"{b}.{k}") for k, v in values.items() if k.endswith("time_constant_s") and v > 0]
    return min(found) if found else None


def step_problems(plan: "Plan") -> list[str]:
    """Why the recording grid or the macro step cannot give trustworthy numbers (empty: they can)."""
    master = plan.scene.master
    if not master.check_steps:
        return []
    weak_fixed = master.coupling != "strong" and not master.adaptive
    problems = []
    ramp = _shortest_ramp(plan)
    if ramp is not None:
        ramp_s, where = ramp
        limit_s = ramp_s / SAMPLES_PER_RAMP
        grids = [("output_interval_s", master.output_interval_s)] if master.coupling in ("strong", "mixed") else []
        if weak_fixed:
            grids.append(("step_s", master.step_s))
        for key, value in grids:
            if value > limit_s * (1 + 1e-9):
                problems.append(
                    f"master.{key} = {value:g} s samples the stroke's shortest ramp ({where} = {ramp_s:g} s) "
                    f"{ramp_s / value:.3g} times; the metrics need {SAMPLES_PER_RAMP} (at most {limit_s:.3g} s). "
                    "Set it smaller, or master.check_steps = false to study the sampling error itself")
    if weak_fixed:
        factor = LOOP_STEP_PER_TIME_CONSTANT[master.coupling]
        for loop in feedback_loops(plan):
            if master.coupling == "mixed" and all(plan.blocks[b].continuous or plan.blocks[b].memoryless for b in loop):
                continue   # inside the mixed coupling's ODE: no step holds anything there
            fastest = _fastest_time_constant(plan, loop)
            if fastest is None:
                continue
            tau_s, where = fastest
            if master.step_s > factor * tau_s * (1 + 1e-9):
                problems.append(
                    f"master.step_s = {master.step_s:g} s is longer than {factor:g}x the fastest time constant on the "
                    f"feedback loop {' <-> '.join(loop)} ({where} = {tau_s:g} s): {master.coupling} coupling holds "
                    f"the fed-back signal over the step, which makes the loop inaccurate or unstable "
                    f"(docs/stability.md). Use master.step_s <= {factor * tau_s:g} s, gauss-seidel, or strong coupling")
    return problems


class PassiveEnergyGuard:
    """Stops the run once a passive block's mechanical energy gain exceeds `factor` times the
    positive work its power ports have done on it since the start.

    For a passive block E(t) - E(0) <= W+(0, t) holds exactly; the factor leaves room for the
    trapezoid rule on the recorded grid (accurate runs of every morphology store at most 0.24 W+,
    weak couplings at the largest allowed steps 0.28 W+; the Morison added-mass force of sessions
    1-2 ran away to 168-750 W+, bench/guard_margins.py).

    Judging starts at `judge_from_s` (one stroke period in): before it both numbers are small and
    their ratio says nothing: in the first milliseconds of a minimum-jerk start it is set by the
    trapezoid rule, and a weak coupling's first steps, which hold the root's acceleration while its angle and rate
    stand still, put energy into the feather that the sampled root power does not show (0.7-2.7 mJ
    on the test bed at 5-10 ms steps, bench/guard_margins.py). Work and energy are still accounted
    from the start. The price: a runaway that starts within the first period runs unjudged until
    its end (docs/stability.md)."""

    def __init__(self, unit: "Unit", energy_index: int, pairs: list[tuple[int, int]], factor: float,
                 judge_from_s: float) -> None:
        self.unit, self.energy_index, self.pairs, self.factor = unit, energy_index, pairs, factor
        self.judge_from_s = judge_from_s
        self.energy0_J: float | None = None
        self.work_in_J = 0.0
        self._last: tuple[float, float] = (0.0, 0.0)

    def _power_W(self) -> float:
        out, inp = self.unit.outbuf, self.unit.inbuf
        return sum(out[k] * inp[i] for k, i in self.pairs)

    def __call__(self, t: float) -> None:
        energy = self.unit.outbuf[self.energy_index]
        power = max(self._power_W(), 0.0)
        if self.energy0_J is None:
            self.energy0_J, self._last = energy, (t, power)
            return
        t_prev, p_prev = self._last
        self.work_in_J += 0.5 * (power + p_prev) * (t - t_prev)
        self._last = (t, power)
        gain = energy - self.energy0_J
        if t >= self.judge_from_s and gain > self.factor * self.work_in_J + ENERGY_FLOOR_J:
            ports = ", ".join(f"{self.unit.output_names[k]} x {self.unit.input_names[i]}" for k, i in self.pairs)
            raise StepError(
                self.unit.name, t,
                f"mechanical energy gained {gain:.3g} J, more than {self.factor:g}x the {self.work_in_J:.3g} J its "
                f"ports ({ports}) put in",
                cause="energy created by the numerics or by the block's own model: a weak coupling whose macro "
                "step is too long for a feedback loop, an integrator tolerance too loose for the block, or a "
                "model that is not passive (docs/stability.md); shorten master.step_s, use strong coupling, "
                "tighten master.rtol, or check the block's equations")


def passive_energy_guards(units: Mapping[str, "Unit"], passivity: Mapping[str, "Passivity | None"], factor: float,
                          judge_from_s: float) -> list[PassiveEnergyGuard]:
    """A guard for every unit whose block declares itself passive (ResolvedBlock.passivity)."""
    if factor <= 0:
        return []
    guards = []
    for name, u in units.items():
        declared = passivity.get(name)
        if declared is None:
            continue
        pairs = [(u.output_names.index(out), u.input_names.index(inp)) for out, inp in declared.power_ports]
        guards.append(PassiveEnergyGuard(u, u.output_names.index(declared.energy_output), pairs, factor, judge_from_s))
    return guards


def watched_outputs(guards: Sequence[PassiveEnergyGuard]) -> set[tuple[str, int]]:
    """(unit, output index) pairs the guards read: the master must evaluate them at every record."""
    return {(g.unit.name, k) for g in guards for k in (g.energy_index, *(k for k, _ in g.pairs))}
