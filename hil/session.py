"""The client side of a map's [session] registers: is this still the device that was tared and
enabled at the start, and is its firmware running?

Behind a Modbus TCP gateway an RS-485 transmitter can restart without the TCP connection
noticing: the replies keep coming, but the tare and the servo's enable and motion are gone,
and a run measured 0.37 for a TR of 1.0 and reported it as complete. Read with every sample,
a changed boot id (or an uptime that went back) is a restart: the hardware blocks note a
`restart` event, the load cell's with `tare_unknown` (featherstar.cosim.swimmer.validity then
excludes every later period), the servo re-enables at its next write. An uptime that stops
moving is a device whose firmware hangs while a gateway serves its last registers: a STALE
fault.
"""
from __future__ import annotations

from typing import Mapping

from .errors import Fault
from .link import FaultSignal
from .registers import SessionField

FROZEN_S = 0.5   # an uptime in ms that stands still this long: the firmware is not running


class SessionWatch:
    """Follows one device's boot id and uptime across the samples of a run."""

    def __init__(self, field: SessionField, frozen_s: float = FROZEN_S) -> None:
        self.field = field
        self.frozen_s = frozen_s
        self.boot_id: int | None = None
        self.uptime_ms: int | None = None
        self._moved_s = 0.0

    def check(self, regs: Mapping[int, int], now_s: float) -> str | None:
        """What a restart since the last sample looked like, or None; raises FaultSignal
        (STALE) for an uptime frozen longer than frozen_s. `now_s`: the client's clock."""
        f = self.field
        boot_id = regs[f.address]
        uptime_ms = (regs[f.uptime_address] << 16) | regs[f.uptime_address + 1]
        restart = None
        if self.boot_id is not None and (boot_id != self.boot_id
                                         or uptime_ms < (self.uptime_ms or 0)):
            restart = (f"boot id {self.boot_id} -> {boot_id}, uptime {uptime_ms} ms: the device "
                       "restarted behind the link")
            self._moved_s = now_s
        elif uptime_ms != self.uptime_ms:
            self._moved_s = now_s
        elif now_s - self._moved_s > self.frozen_s:
            raise FaultSignal(Fault.STALE, f"uptime frozen at {uptime_ms} ms for "
                                           f"{now_s - self._moved_s:.3f} s: the device's firmware "
                                           "is not running (a gateway serving its last registers?)")
        self.boot_id, self.uptime_ms = boot_id, uptime_ms
        return restart
