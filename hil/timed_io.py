"""The PC's side of device-timed runs, register by register: clock synchronisation, trajectory
upload and start, and block reads of a device's sample ring (featherstar.hil.timed_registers).

Every function takes a started hardware block (featherstar.hil.blocks: its link, map and unit)
and raises FaultSignal on a bus failure, as the links do.
"""
from __future__ import annotations

import math
import struct
import time
from dataclasses import dataclass
from typing import Sequence

from .codec import decode_value
from .device import ModbusDevice
from .errors import Fault
from .link import FaultSignal
from .modbus_server import MAX_READ, MAX_WRITE
from .registers import NumberField
from .timed_registers import ENTRY_REGISTERS, LogField, PlayerState, TrajectoryField

_WRAP_US = 1 << 32
SYNC_READS = 5          # clock reads per synchronisation; the one with the shortest round trip wins


def _u32(words: Sequence[int]) -> int:
    return (words[0] << 16) | words[1]


def _words(x: int) -> list[int]:
    x %= _WRAP_US
    return [x >> 16, x & 0xFFFF]


@dataclass(frozen=True)
class ClockSync:
    """device clock = pc clock + offset_s, at pc time `pc_s`, to within +- rtt_s / 2."""

    pc_s: float
    offset_s: float
    rtt_s: float


class DeviceClock:
    """One device's microsecond clock, unwrapped, and its offset to the PC's monotonic clock."""

    def __init__(self, block: ModbusDevice) -> None:
        self.block = block
        self.field = block.map.timed.clock
        self.syncs: list[ClockSync] = []
        self._last_us: int | None = None
        self._wraps = 0

    def unwrap_s(self, raw_us: int) -> float:
        """Device seconds since boot from a 32-bit microsecond stamp near the last one."""
        if self._last_us is not None and raw_us < self._last_us - _WRAP_US // 2:
            self._wraps += 1
        self._last_us = raw_us
        return (self._wraps * _WRAP_US + raw_us) / 1e6

    def sync(self) -> ClockSync:
        best: ClockSync | None = None
        b = self.block
        for _ in range(SYNC_READS):
            t0 = time.monotonic()
            words = b.link.read(b.map.read_function, self.field.address, 2, b.url.unit)
            t1 = time.monotonic()
            device_s = self.unwrap_s(_u32(words))
            candidate = ClockSync(0.5 * (t0 + t1), device_s - 0.5 * (t0 + t1), t1 - t0)
            if best is None or candidate.rtt_s < best.rtt_s:
                best = candidate
        self.syncs.append(best)
        return best

    def to_pc_s(self, device_s: float) -> float:
        """PC time of a device time, the offset interpolated between the syncs (drift)."""
        first, last = self.syncs[0], self.syncs[-1]
        if last.pc_s - first.pc_s < 1e-3:
            return device_s - first.offset_s
        rate = (last.offset_s - first.offset_s) / (last.pc_s - first.pc_s)
        # device = pc + o0 + rate (pc - pc0)  =>  pc = (device - o0 + rate pc0) / (1 + rate)
        return (device_s - first.offset_s + rate * first.pc_s) / (1.0 + rate)

    def drift_ppm(self) -> float:
        first, last = self.syncs[0], self.syncs[-1]
        span = last.pc_s - first.pc_s
        return math.nan if span < 1e-3 else (last.offset_s - first.offset_s) / span * 1e6


def upload_trajectory(servo: ModbusDevice, period_s: float, samples_rad: Sequence[float]) -> None:
    """Write the sample period, the count and the samples (signed 16 bit, the setpoint's unit
    with the table's decimals); the player is armed later by `start_trajectory`."""
    traj: TrajectoryField = servo.map.timed.trajectory
    sp = servo.map.setpoint
    scale = 10 ** traj.decimals / sp.to_si
    counts = [max(-32768, min(32767, round(x * scale))) for x in samples_rad]
    raw = list(struct.unpack(f">{len(counts)}H", struct.pack(f">{len(counts)}h", *counts)))
    link, unit = servo.link, servo.url.unit
    link.write_one(traj.period_us_address, round(period_s * 1e6), unit)
    link.write_one(traj.count_address, len(raw), unit)
    for k in range(0, len(raw), MAX_WRITE):
        link.write(traj.data_address + k, raw[k:k + MAX_WRITE], unit)


def start_trajectory(servo: ModbusDevice, device_start_s: float) -> None:
    traj = servo.map.timed.trajectory
    servo.link.write(traj.start_address, _words(round(device_start_s * 1e6)), servo.url.unit)


def player_state(servo: ModbusDevice) -> PlayerState:
    traj = servo.map.timed.trajectory
    word = servo.link.read(servo.map.read_function, traj.state_address, 1, servo.url.unit)[0]
    try:
        return PlayerState(word)
    except ValueError:
        raise FaultSignal(Fault.OUT_OF_RANGE, f"trajectory state register reads {word}") from None


def start_log(block: ModbusDevice, period_s: float) -> None:
    log: LogField = block.map.timed.log
    block.link.write_one(log.period_us_address, round(period_s * 1e6), block.url.unit)


class LogReader:
    """Reads a device's sample ring in blocks; notes samples lost to an overrun."""

    def __init__(self, block: ModbusDevice, field: NumberField, clock: DeviceClock) -> None:
        self.block, self.field, self.clock = block, field, clock
        self.log: LogField = block.map.timed.log
        self.next_k = 0                 # the next sample to read
        self.lost = 0                   # samples overwritten before they were read
        self.times_s: list[float] = []  # device seconds
        self.values: list[float] = []   # SI

    def head(self) -> int:
        b = self.block
        return _u32(b.link.read(b.map.read_function, self.log.head_address, 2, b.url.unit))

    def poll(self) -> int:
        """Read every sample taken since the last poll; returns how many were lost now."""
        head = self.head()
        lost_now = max(0, head - self.next_k - self.log.capacity)
        self.next_k += lost_now
        self.lost += lost_now
        per_read = MAX_READ // ENTRY_REGISTERS
        b = self.block
        while self.next_k < head:
            slot = self.next_k % self.log.capacity
            n = min(head - self.next_k, per_read, self.log.capacity - slot)
            words = b.link.read(b.map.read_function, self.log.entry_address(self.next_k),
                                n * ENTRY_REGISTERS, b.url.unit)
            for i in range(n):
                entry = words[i * ENTRY_REGISTERS:(i + 1) * ENTRY_REGISTERS]
                self.times_s.append(self.clock.unwrap_s(_u32(entry[:2])))
                self.values.append(decode_value(self.field, entry[2:]) * self.field.to_si)
            self.next_k += n
        return lost_now
