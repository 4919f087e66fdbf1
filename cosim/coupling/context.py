"""What changes during one run, apart from the units' own states: the time, the recording, the
solver statistics and the deadline misses (Drake's Context, in small). A Simulator owns one; the
couplings are handed the parts they write."""
from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from ..errors import StepError
from ..scene.data import PortRef
from ..scene.guards import PassiveEnergyGuard


@dataclass
class Context:
    """The simulation time and the run's bookkeeping."""

    t: float = 0.0
    stats: dict[str, Any] = field(default_factory=dict)
    late_steps: list[tuple[float, float]] = field(default_factory=list)  # realtime: (t, late_s)
    loop_solvers: list[Any] = field(default_factory=list)  # schedule.LoopSolver, for their statistics


class Recording:
    """The signals recorded at every communication point (or output time), and the guards that
    judge each recorded point. `keep_rows = False` runs the guards without keeping the rows (a
    plant stepped for hours)."""

    def __init__(self, requested: Sequence[PortRef], refs: Sequence[tuple[ctypes.Array, int]],
                 guards: Sequence[PassiveEnergyGuard], *, keep_rows: bool = True,
                 progress: Callable[[float], None] | None = None) -> None:
        self.requested = list(requested)
        self.refs = list(refs)
        self.guards = list(guards)
        self.keep_rows = keep_rows
        self.progress = progress
        self.times: list[float] = []
        self.rows: list[list[float]] = []
        self._checked = 0   # rows already checked finite by check_rows

    def record(self, t: float) -> None:
        """Record a checked point, then let the guards judge it (the point that trips one is kept)."""
        if self.keep_rows:
            self.times.append(t)
            self.rows.append([buf[k] for buf, k in self.refs])
        for guard in self.guards:
            guard(t)

    def tick(self, t: float) -> None:
        if self.progress is not None:
            self.progress(t)

    def check_rows(self) -> None:
        """Stop at the first non-finite recorded value since the last check (rows from it dropped)."""
        if len(self.rows) <= self._checked:
            return
        arr = np.asarray(self.rows[self._checked:], dtype=float)
        bad = ~np.isfinite(arr)
        if bad.any():
            r, c = np.argwhere(bad)[0]
            r += self._checked
            ref = self.requested[c]
            t = self.times[r]
            value = self.rows[r][c]
            del self.times[r:], self.rows[r:]
            raise StepError(ref.block, t, f"output {ref.port} is {value}",
                            cause="the block's model blew up or divided by zero; check its parameters and inputs")
        self._checked = len(self.rows)

    def truncate_after(self, t: float) -> None:
        """Drop the points recorded after t (a restored state continues from t)."""
        n = len(self.times)
        while n and self.times[n - 1] > t:
            n -= 1
        del self.times[n:], self.rows[n:]
        self._checked = min(self._checked, n)
