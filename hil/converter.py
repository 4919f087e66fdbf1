"""The emulated load cell's converter: readings that integrate the force, as a sigma-delta ADC's do.

Load-cell transmitters convert with sigma-delta ADCs: a reading is the mean force over the
conversion, not an instant of it. `IntegratingConverter` gives each reading as the mean force
since the previous reading, over at most `conversion_s` (a converter integrates no longer than
its conversion: a tare after a pause is the last conversion, not the pause), from the plant's
impulse (the time integral of its force). Readings that tile the time are then unbiased: on a
bench loop the servo's acceleration, hence the thrust, jumps at every setpoint the client
writes, and instantaneous samples taken just after each write biased a plain feather's mean
thrust by +14 % (docs/bench-loop.md).
"""
from __future__ import annotations

import collections

#: The longest a reading integrates the force (a 50 samples/s converter); readings closer together
#: integrate from the previous one.
CONVERSION_S = 0.02


class IntegratingConverter:
    """Readings of a force from its impulse I(t) = ∫F dt, noted as plant time advances."""

    def __init__(self, t_s: float, impulse_Ns: float, conversion_s: float = CONVERSION_S) -> None:
        if not conversion_s > 0:
            raise ValueError(f"conversion_s = {conversion_s!r} must be > 0")
        self.conversion_s = conversion_s
        self._impulses: collections.deque[tuple[float, float]] = collections.deque()
        self.reset(t_s, impulse_Ns)

    def reset(self, t_s: float, impulse_Ns: float) -> None:
        """Start again at (t_s, impulse_Ns): the plant was reset; nothing converted yet."""
        self._impulses.clear()
        self._impulses.append((t_s, impulse_Ns))
        self._last: tuple[float, float | None] = (t_s, None)

    def note(self, t_s: float, impulse_Ns: float) -> None:
        """The plant reached t_s with this impulse (keep what the next conversion can need)."""
        history = self._impulses
        history.append((t_s, impulse_Ns))
        while len(history) > 2 and history[1][0] <= t_s - self.conversion_s:
            history.popleft()

    def read(self, force_now_N: float) -> float:
        """The mean force since the previous reading (at most the last conversion_s) up to the
        last noted time; `force_now_N` when no time has passed since the start or a reset, the
        previous reading when none has passed since it."""
        t1_s, impulse1_Ns = self._impulses[-1]
        t_last_s, mean_N = self._last
        t0_s = max(t_last_s, t1_s - self.conversion_s, self._impulses[0][0])
        if t1_s > t0_s:
            mean_N = (impulse1_Ns - self._impulse_at(t0_s)) / (t1_s - t0_s)
        elif mean_N is None:
            mean_N = force_now_N
        self._last = (t1_s, mean_N)
        return mean_N

    def _impulse_at(self, t_s: float) -> float:
        """The impulse at t_s (linear between the noted times that bracket it)."""
        previous = self._impulses[0]
        for entry in self._impulses:
            if entry[0] >= t_s:
                if entry[0] == previous[0]:
                    return entry[1]
                share = (t_s - previous[0]) / (entry[0] - previous[0])
                return previous[1] + share * (entry[1] - previous[1])
            previous = entry
        return previous[1]
