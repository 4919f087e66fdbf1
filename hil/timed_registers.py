"""Register-map tables of device-timed runs: the device's clock, an uploaded trajectory and a
ring buffer of time-stamped samples (docs/hil.md, "Device-timed runs", for firmware authors).

    [clock]       address: two registers (ABCD), the device's clock in microseconds since boot,
                  unsigned, wrapping at 2^32 (71.6 min). Read-only.
    [trajectory]  servo: the stroke the device plays on its own clock.
                  period_us_address   one register: the sample period, microseconds (writable)
                  count_address       one register: the number of samples, 1..capacity (writable)
                  start_address       two registers: the device-clock time of sample 0, us;
                                      writing it arms the player (writable)
                  state_address       one register: 0 idle, 1 armed, 2 playing, 3 done (read-only)
                  data_address        `capacity` registers: signed 16-bit samples of the
                                      setpoint in its unit with `decimals` (default 2) (writable)
                  The servo holds sample 0 until the start, then sample k from start + k period
                  (held, not interpolated), and the last sample after the end. A setpoint
                  written, a restart or the watchdog stops it (state 0).
    [log]         both: samples the map's measured field ([value], [position]) on the device's
                  clock into a ring buffer.
                  period_us_address   one register (writable): writing a period restarts the log
                                      (head 0, the first sample one period later); 0 stops it
                  head_address        two registers (ABCD, read-only): samples taken since
                  ring_address        capacity x 4 registers (read-only): sample k at entry
                                      k mod capacity = time taken (us, two registers ABCD), then
                                      the value as the measured field encodes it
                  For an integrating load cell a sample is the mean force over its period.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any

from .map_reader import MapReader, map_address

ENTRY_REGISTERS = 4          # time (2) + value (2)
MAX_CAPACITY = 16000


class PlayerState(enum.IntEnum):
    IDLE = 0
    ARMED = 1
    PLAYING = 2
    DONE = 3


@dataclass(frozen=True)
class ClockField:
    address: int


@dataclass(frozen=True)
class TrajectoryField:
    period_us_address: int
    count_address: int
    start_address: int
    state_address: int
    data_address: int
    capacity: int
    decimals: int = 2


@dataclass(frozen=True)
class LogField:
    period_us_address: int
    head_address: int
    ring_address: int
    capacity: int

    def entry_address(self, k: int) -> int:
        return self.ring_address + (k % self.capacity) * ENTRY_REGISTERS


@dataclass(frozen=True)
class TimedTables:
    clock: ClockField | None
    trajectory: TrajectoryField | None
    log: LogField | None

    def spans(self, read_space: str) -> list[tuple[str, str, int, int, bool]]:
        """(space, name, protocol address, register count, writable) of every table."""
        out = []
        if self.clock is not None:
            out.append((read_space, "[clock]", self.clock.address, 2, False))
        if (t := self.trajectory) is not None:
            out += [("holding", "[trajectory] period_us_address", t.period_us_address, 1, True),
                    ("holding", "[trajectory] count_address", t.count_address, 1, True),
                    ("holding", "[trajectory] start_address", t.start_address, 2, True),
                    (read_space, "[trajectory] state_address", t.state_address, 1, False),
                    ("holding", "[trajectory] data_address", t.data_address, t.capacity, True)]
        if (g := self.log) is not None:
            out += [("holding", "[log] period_us_address", g.period_us_address, 1, True),
                    (read_space, "[log] head_address", g.head_address, 2, False),
                    (read_space, "[log] ring_address", g.ring_address,
                     g.capacity * ENTRY_REGISTERS, False)]
        return out


def parse_timed(r: MapReader, doc: dict[str, Any], kind: str, base: int) -> TimedTables:
    clock = r.table(doc, "clock", required=False)
    trajectory = r.table(doc, "trajectory", required=False) if kind == "servo" else None
    log = r.table(doc, "log", required=False)
    clock_field = traj_field = log_field = None
    if clock is not None:
        r.check_keys("clock", clock, {"address"})
        clock_field = ClockField(map_address(r, "clock", clock, "address", base))
    if trajectory is not None:
        keys = ("period_us_address", "count_address", "start_address", "state_address",
                "data_address")
        r.check_keys("trajectory", trajectory, {*keys, "capacity", "decimals"})
        traj_field = TrajectoryField(
            *(map_address(r, "trajectory", trajectory, k, base) for k in keys),
            capacity=r.integer("trajectory", trajectory, "capacity", 1, MAX_CAPACITY, True),
            decimals=r.integer("trajectory", trajectory, "decimals", 0, 4) or 2)
    if log is not None:
        keys = ("period_us_address", "head_address", "ring_address")
        r.check_keys("log", log, {*keys, "capacity"})
        log_field = LogField(*(map_address(r, "log", log, k, base) for k in keys),
                             capacity=r.integer("log", log, "capacity", 1,
                                                MAX_CAPACITY, True))
    if (traj_field is not None or log_field is not None) and clock_field is None:
        raise r.fail("[clock]", "missing: [trajectory] and [log] run on the device's clock")
    return TimedTables(clock_field, traj_field, log_field)
