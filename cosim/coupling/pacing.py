"""Wall-clock pacing of a real-time run (hardware in the loop): the one pacing loop, and the
points where a stop asked for from outside is honoured.

The Simulator calls the pacer before every macro step of a `master.realtime` scene. A step may
not start before its wall-clock time; one that starts more than a step late missed its deadline
(the device saw a stale command) and is noted in the Context's `late_steps`, which
featherstar.cosim.swimmer.validity judges per period. The clock starts at the first step.

**Stops from outside.** A signal handler that raised at once could land anywhere, e.g. in the
middle of the safe stop that follows a device fault (the servo's safe-position retry, the
writing of the partial data). So a real-time run's handler only records the signal
(`STOP.request`), and the run raises RunInterrupted where stopping is safe: here, before every
step, and in the hardware blocks' waiting loops (`STOP.raise_if_requested`). Once the stop has
begun nothing raises any more: the safe stop runs to its end, then the command exits with the
recorded signal's status.
"""
from __future__ import annotations

import time

from ..errors import RunInterrupted
from .context import Context


class StopRequest:
    """The first stop signal of a run, kept until the run honours it at a safe point."""

    def __init__(self) -> None:
        self.pending: str | None = None
        self.repeats = 0

    def clear(self) -> None:
        self.pending, self.repeats = None, 0

    def request(self, signal_name: str) -> bool:
        """Record a stop signal; True for the first one of the run."""
        if self.pending is not None:
            self.repeats += 1
            return False
        self.pending = signal_name
        return True

    def raise_if_requested(self) -> None:
        """Raise RunInterrupted if a stop was asked for (call only where stopping is safe)."""
        if self.pending is not None:
            raise RunInterrupted(self.pending)


#: Signals are process-wide, so is the request they leave.
STOP = StopRequest()


class RealTimePacer:
    """`pacer(t, h)` before the macro step from simulation time t of length h."""

    def __init__(self, context: Context) -> None:
        self.context = context
        self.t0: float | None = None
        self.wall0 = 0.0
        self.misses = 0
        self.worst_lateness_s = 0.0

    def __call__(self, t: float, h: float) -> None:
        STOP.raise_if_requested()
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
