"""What an emulated device keeps about its own life: the boot session and the command watchdog.

A real transmitter behind a Modbus TCP gateway can restart (a brown-out, a watchdog reset of its
own firmware) while the gateway keeps the TCP connection up: the client sees no reconnect, yet
the tare and the servo's enable and motion are gone. `BootSession` is the firmware side of the
maps' [session] table: an id drawn at every boot (never 0, never the previous one) and the
milliseconds since boot, both served on every read. `CommandWatchdog` is the servo firmware's
[watchdog]: no command (a write) for `timeout_ms` and the servo goes to its safe position, which is all
that protects a bench from a client killed with -9 or a PC that lost power.
"""
from __future__ import annotations

import random
import time
from typing import Callable

Clock = Callable[[], float]
_UPTIME_WRAP_MS = 1 << 32


class BootSession:
    """The boot id and the uptime of one device."""

    def __init__(self, rng: random.Random, clock: Clock = time.monotonic) -> None:
        self._rng, self._clock = rng, clock
        self.id = 0
        self.boots = 0
        self.boot()

    def boot(self) -> None:
        """A (re)boot: a new id and the uptime back to zero."""
        previous = self.id
        while self.id in (0, previous):
            self.id = self._rng.randrange(1, 1 << 16)
        self.boot_s = self._clock()
        self.boots += 1

    def uptime_ms(self) -> int:
        return int((self._clock() - self.boot_s) * 1e3) % _UPTIME_WRAP_MS

    def words(self) -> tuple[int, list[int]]:
        """(id register, the two uptime registers ABCD)."""
        up = self.uptime_ms()
        return self.id, [up >> 16, up & 0xFFFF]


class CommandWatchdog:
    """Trips once when armed and no command came for `timeout_s`; fed by every write (a
    monitor that only reads must not keep a dead client's last command alive)."""

    def __init__(self, clock: Clock = time.monotonic) -> None:
        self._clock = clock
        self.timeout_s: float | None = None     # None: not armed (the client never set it)
        self.last_request_s = clock()
        self.tripped = False
        self.trips = 0

    def arm(self, timeout_ms: int) -> None:
        self.timeout_s = timeout_ms / 1e3 if timeout_ms > 0 else None

    def feed(self) -> None:
        self.last_request_s = self._clock()

    def expired(self) -> bool:
        """True once per silence longer than the timeout (the servo must go safe now)."""
        if self.timeout_s is None or self.tripped:
            return False
        if self._clock() - self.last_request_s <= self.timeout_s:
            return False
        self.tripped = True
        self.trips += 1
        return True

    def resume(self) -> None:
        """A new setpoint: the servo follows commands again."""
        self.tripped = False


class RestWatch:
    """Whether the plant has sat still long enough that integrating it would change nothing the
    registers show (the idle emulator then computes nothing: its CPU use near zero).

    Still = |rate| below `rate_rad_s` and |thrust| below `thrust_N` (a thousandth of the load
    cell's noise), for `after_s` of plant time on end. Anything that can move the plant (a
    write, a reboot, a reset, the watchdog, a device-timed stroke) calls `disturb()`."""

    def __init__(self, rate_rad_s: float = 1e-4, thrust_N: float = 1e-5,
                 after_s: float = 1.0) -> None:
        self.rate_rad_s, self.thrust_N, self.after_s = rate_rad_s, thrust_N, after_s
        self.still_s = 0.0

    def note(self, dt_s: float, rate_rad_s: float, thrust_N: float) -> None:
        still = abs(rate_rad_s) < self.rate_rad_s and abs(thrust_N) < self.thrust_N
        self.still_s = self.still_s + dt_s if still else 0.0

    def disturb(self) -> None:
        self.still_s = 0.0

    @property
    def resting(self) -> bool:
        return self.still_s >= self.after_s
