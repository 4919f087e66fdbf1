"""Wall-clock pacing of a real-time run (hardware in the loop): the one pacing loop.

The Simulator calls the pacer before every macro step of a `master.realtime` scene. A step may
not start before its wall-clock time; one that starts more than a step late missed its deadline
(the device saw a stale command) and is noted in the Context's `late_steps`, which
featherstar.cosim.swimmer.validity judges per period. The clock starts at the first step.
"""
from __future__ import annotations

import time

from .context import Context


class RealTimePacer:
    """`pacer(t, h)` before the macro step from simulation time t of length h."""

    def __init__(self, context: Context) -> None:
        self.context = context
        self.t0: float | None = None
        self.wall0 = 0.0
        self.misses = 0
        self.worst_lateness_s = 0.0

    def __call__(self, t: float, h: float) -> None:
        now = time.perf_counter()
        if self.t0 is None:
            self.t0, self.wall0 = t, now
        lateness = now - self.wall0 - (t - self.t0)
        if lateness < 0:
            time.sleep(-lateness)
        elif lateness > h:
            self.misses += 1
            self.context.late_steps.append((t, lateness))
        self.worst_lateness_s = max(self.worst_lateness_s, lateness)
        self.context.stats.update(deadline_misses=self.misses, worst_lateness_s=self.worst_lateness_s)
