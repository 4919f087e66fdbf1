"""The firmware side of device-timed runs, for the emulator: a trajectory player and a sample
log, both on the device's clock (featherstar.hil.timed_registers describes the registers).

Both are pure functions of device time: the emulator advances its plant from one event (a
trajectory sample switching, a log sample due) to the next, whenever it gets the CPU, so what
the devices do and record does not depend on when the emulator process was scheduled, as on a
bench whose devices have their own microcontrollers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .timed_registers import PlayerState


@dataclass
class TrajectoryPlayer:
    """Plays `samples_rad` (held, one per `period_s`) from device time `start_s` on."""

    period_s: float = 0.0
    samples_rad: list[float] = field(default_factory=list)
    start_s: float = math.inf
    aborted: bool = False

    def arm(self, period_s: float, samples_rad: list[float], start_s: float) -> None:
        self.period_s, self.samples_rad, self.start_s = period_s, samples_rad, start_s
        self.aborted = False

    def abort(self) -> None:
        """The watchdog tripped, or the device restarted: the stroke stops where it is."""
        self.aborted = True

    @property
    def end_s(self) -> float:
        return self.start_s + len(self.samples_rad) * self.period_s

    def state(self, t_s: float) -> PlayerState:
        if not self.samples_rad or self.aborted:
            return PlayerState.IDLE
        if t_s < self.start_s:
            return PlayerState.ARMED
        return PlayerState.PLAYING if t_s < self.end_s else PlayerState.DONE

    def setpoint_rad(self, t_s: float) -> float | None:
        """The setpoint at device time t_s, None when nothing is to be played."""
        if not self.samples_rad or self.aborted:
            return None
        k = math.floor((t_s - self.start_s) / self.period_s + 1e-9)
        return self.samples_rad[min(max(k, 0), len(self.samples_rad) - 1)]

    def next_switch_s(self, t_s: float) -> float:
        """The first sample switch strictly after t_s (inf when none is left)."""
        if not self.samples_rad or self.aborted or t_s >= self.end_s - self.period_s:
            return math.inf
        k = max(math.floor((t_s - self.start_s) / self.period_s + 1e-9) + 1, 1)
        return self.start_s + k * self.period_s


@dataclass
class SampleLog:
    """Samples taken every `period_s` of device time from `start_s`, in a ring of `capacity`."""

    capacity: int
    period_s: float | None = None
    start_s: float = 0.0
    head: int = 0                                    # samples taken since the start

    def restart(self, period_s: float | None, now_s: float) -> None:
        self.period_s, self.start_s, self.head = period_s, now_s, 0

    def next_due_s(self) -> float:
        """Device time of the next sample (inf when the log is off)."""
        if self.period_s is None:
            return math.inf
        return self.start_s + (self.head + 1) * self.period_s
