"""The bench as an `Objective`: a stroke run on the devices, kept only when its data can be trusted.

Each call rests the feather (`rest_s`, servo at its safe position, where the previous run's
close left it; counted from the end of the previous run, so the optimizer's own time between
runs is part of the rest, not added to it), then runs settling plus measured periods in real time through the scene
(`featherstar.optimizer.bench.run.run_on_bench`). A run is **discarded** (`DiscardedRun`) when anywhere in it

- a step started more than `featherstar.cosim.swimmer.validity.MAX_LATE_S` (0.05 s) late (a stall), or
- more than `featherstar.cosim.swimmer.validity.MAX_MISS_FRACTION` (10 %) of the steps missed their deadline, or
- a device needed a recovery (a data gap) or reconnected, or reported its plant behind real
  time (an emulator's status lag bit), or
- the master excluded a period of the measured window or called the run incomplete, or
- the measured window has no negative thrust (TR infinite: the load cell tares at the start of
  every run, so a feather still moving from the last run offsets the whole recording), or
- its samples do not span the run (a streamed run stamps each sample with the PC's clock at the
  read: a PC that lost time can end the record short of the last period's end).

This is stricter than `featherstar run`, which keeps a run with half its periods valid: the
optimizer compares evaluations with each other, so every one must be measured over the same
whole window. Settling periods count too, because a stall there changes the state the
measurement starts from. `Retrying` repeats a discarded run, reporting each discard.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from ...cosim.swimmer.validity import MAX_LATE_S, MAX_MISS_FRACTION
from ..objective import RUN_LENGTH_OVERRIDE, Overrides, Trace
from .run import BenchFault, BenchRun, run_on_bench

DEFAULT_REST_S = 5.0
DEFAULT_MAX_ATTEMPTS = 3
SETTLE_OVERRIDE = "metrics.settle_periods"


class DiscardedRun(Exception):
    """A bench run whose data cannot be trusted; `reasons` says why, one line each."""

    def __init__(self, reasons: list[str], summary: Mapping[str, Any]) -> None:
        super().__init__("; ".join(reasons))
        self.reasons = reasons
        self.summary = dict(summary)


def discard_reasons(run: BenchRun) -> list[str]:
    """Why this run must not be used (empty: keep it). Thresholds: see the module docstring."""
    s = run.summary
    reasons = []
    steps = max(int((s.get("stats") or {}).get("macro_steps", 0) or 0), 1)
    if s.get("worst_lateness_s", 0.0) > MAX_LATE_S:
        reasons.append(f"a step started {s['worst_lateness_s']:.3f} s late (limit {MAX_LATE_S} s)")
    if s.get("deadline_misses", 0) > MAX_MISS_FRACTION * steps:
        reasons.append(f"{s['deadline_misses']} of {steps} steps missed their deadline "
                       f"(limit {MAX_MISS_FRACTION:.0%})")
    if s.get("gaps", 0):
        reasons.append(f"{s['gaps']} data gap(s)")
    if s.get("reconnects", 0):
        reasons.append(f"{s['reconnects']} device reconnect(s)")
    if s.get("lags", 0):
        reasons.append(f"{s['lags']} report(s) of the device's plant behind real time")
    invalid = (s.get("validity") or {}).get("invalid_periods") or []
    if invalid:
        reasons.append(f"{len(invalid)} measured period(s) excluded: {invalid[0]['reasons'][0]}")
    window = s.get("window_s")
    if window and len(run.thrust_N):
        inside = (run.time_s >= window[0]) & (run.time_s <= window[1])
        if inside.any() and run.thrust_N[inside].min() >= 0:
            reasons.append("no negative thrust in the measured window (TR infinite): a tare taken while the "
                           "feather still moved? lengthen --rest-s")
    if not run.complete and not reasons:
        reasons.append(s.get("incomplete_reason", "the master marked the run incomplete"))
    return reasons


def coverage_reasons(time_s: np.ndarray, duration_s: float) -> list[str]:
    """Why samples stamped at `time_s` (s) cannot measure a run of `duration_s` (empty: they can).
    The metrics need whole periods; a record may end up to one of its own sample intervals short
    (a device's clock samples on its own grid), not more."""
    span_s = float(time_s[-1] - time_s[0]) if len(time_s) else 0.0
    interval_s = float(np.median(np.diff(time_s))) if len(time_s) > 2 else 0.0
    if span_s < duration_s - interval_s - 1e-9:
        return [f"the samples span {span_s:.3f} s of the {duration_s:.3f} s run (their read times fell "
                "short: the PC ran late)"]
    return []


@dataclass
class RestClock:
    """When the previous run on a bench ended (time.monotonic, s; None before the first)."""

    ended_s: float | None = None

    def rest_left_s(self, rest_s: float, now_s: float) -> float:
        """How much longer to rest for `rest_s` since the previous run ended."""
        return rest_s if self.ended_s is None else max(0.0, rest_s - (now_s - self.ended_s))


@dataclass(frozen=True)
class BenchObjective:
    """One attempt of a stroke on the bench (the `Objective` protocol); raises DiscardedRun.

    The rest counts from the previous run's end (`RestClock`): the load cell tares at the start
    of every run, and a feather that still rings, or water still moving, offsets the whole
    recording by the force at that moment. On the emulator's plate-wake bench the same stroke
    after the same stroke measured TR 1.109, 0.968, 1.056, 1.010 after 3, 4, 5, 8 s of rest (the
    tare -4.4, +2.3, -2.0, +0.2 mN: the feather rings); a rest that also waited for the
    optimizer made its measurements depend on how long the optimizer computed (the discrepancy
    prior's seeded strokes measured 0.05 below the seeded prior's same strokes)."""

    scene: str
    hardware: Mapping[str, str]
    overrides: Mapping[str, str | float] = field(default_factory=dict)
    settle_periods: int = 3
    rest_s: float = DEFAULT_REST_S
    rest_clock: RestClock = field(default_factory=RestClock, compare=False, repr=False)

    def __call__(self, overrides: Overrides, duration_s: float) -> Trace:
        time.sleep(self.rest_clock.rest_left_s(self.rest_s, time.monotonic()))
        started = time.perf_counter()
        try:
            run = run_on_bench(self.scene, self.hardware, {
                **self.overrides, **overrides, RUN_LENGTH_OVERRIDE: duration_s, SETTLE_OVERRIDE: self.settle_periods})
        finally:
            self.rest_clock.ended_s = time.monotonic()
        reasons = discard_reasons(run) + coverage_reasons(run.time_s, duration_s)
        if reasons:
            raise DiscardedRun(reasons, run.summary)
        return Trace(run.time_s, run.thrust_N, time.perf_counter() - started)

    def describe(self) -> dict:
        """For the log header: what makes two studies comparable (not the device addresses,
        which may change when a device is restarted)."""
        return {"scene": self.scene, "overrides": dict(self.overrides), "rest_s": self.rest_s,
                "discard_limits": {"max_late_s": MAX_LATE_S, "max_miss_fraction": MAX_MISS_FRACTION,
                                   "gaps": 0, "reconnects": 0, "lags": 0, "excluded_periods": 0}}


@dataclass(frozen=True)
class Retrying:
    """Repeat a discarded run up to `max_attempts` times, calling `on_discard(reasons, summary)`
    for each; then stop the study with BenchFault (the bench is not keeping time)."""

    objective: BenchObjective
    on_discard: Callable[[list[str], Mapping[str, Any]], None]
    max_attempts: int = DEFAULT_MAX_ATTEMPTS

    def __call__(self, overrides: Overrides, duration_s: float) -> Trace:
        last = ""
        for _ in range(self.max_attempts):
            try:
                return self.objective(overrides, duration_s)
            except DiscardedRun as discarded:
                self.on_discard(discarded.reasons, discarded.summary)
                last = str(discarded)
        raise BenchFault(f"{self.max_attempts} runs in a row were discarded (last: {last}); the bench "
                         "is not keeping time: check the machine's load and the link, then --resume")
