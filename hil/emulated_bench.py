"""A Modbus TCP bench emulator: a load-cell transmitter and a servo controller on one server.

The load cell answers as unit 1 and the servo as unit 2 (an RS-485 line behind a TCP gateway),
each behind its register map. Every request first advances the plant to the current wall-clock
time, and so does a tick every `TICK_S` while nobody asks (a feather left alone between runs
moves on as it would on the bench), so the emulator behaves like the bench whatever the
client's request rate.

**Behind real time.** The plant's state is served late when advancing it took longer than
`lag_limit_s` of wall-clock time, when the event loop was held up that long (the process was not
scheduled: the tick came late), or when plant time was dropped (`max_advance_s`). The emulator
then sets the `lag_bit` of both devices' status words (if their maps have one) until a client
has read each of them, and counts it (`lag_events`, `worst_lag_s`): a client sees the lag at its next
status read and can discard the data, which on a loaded machine otherwise lag the clock
without the client noticing. The servo
follows setpoints only once enabled (if its map has [enable]); the load cell reports the
plant's thrust plus a preload (the feather's weight in water, removed by tare) plus Gaussian
noise, as kg-force or whatever unit its map says, with the stable and overload bits.

**An integrating load cell.** When the plant keeps `impulse_Ns` (both plants here do), a reading
(and a tare) is the mean force since the previous reading, over at most the last 20 ms, as a
sigma-delta converter reports (featherstar.hil.converter); otherwise the instantaneous force.

Served by featherstar.hil.emulator (`serve`, `start_emulator`, `spawn_emulator`).
"""
from __future__ import annotations

import asyncio
import logging
import math
import random
import threading
import time
from typing import Callable

from .codec import decode_value, encode_status, encode_value
from .converter import CONVERSION_S, IntegratingConverter
from .errors import HILError
from .modbus_server import (DEVICE_FAILURE, ILLEGAL_ADDRESS, ILLEGAL_VALUE, RateLimitedLog,
                            spaces_for)
from .lifecycle import BootSession, CommandWatchdog, RestWatch
from .plant import FlatPlatePlant, Plant
from .timed_emulation import TimedFirmware
from .registers import (Function, LoadCellMap, NumberField, ServoMap, SessionField, Status,
                        StatusField)

LOADCELL_UNIT = 1
SERVO_UNIT = 2
LOADCELL_CAPACITY_N = 3.0 * 9.80665     # the bench's 0-3 kg cell
REGISTER_DECIMALS = 3                   # what the emulator puts in a decimals register
FAULTS = ("freeze", "silent", "exception", "overload", "error")
SERVO_RANGE_RAD = (-math.pi / 2, math.pi / 2)   # setpoint clamp when the map gives no range
IDLE_TIMEOUT_S = 30.0                   # close connections silent for this long
_STABLE_RATE_RAD_S = 0.05              # below this the feather (and the cell) is at rest
TICK_S = 0.02                           # the plant is advanced at least this often, requests or not
IDLE_TICK_S = 0.25                      # ... once it rests (nothing to integrate)
IDLE_WATCHDOG_TICK_S = 0.1              # ... once it rests with the servo's watchdog armed
WATCHDOG_LATE_S = 0.05                  # a tick later than this does not judge the watchdog
# A served state older than this is "behind real time": 5 steps of a 250 Hz client, 0.1 rad of
# the servo's fastest travel, 2 % of a 1 s stroke.
LAG_LIMIT_S = 0.02
# While a trajectory plays or a log runs, the plant is advanced in pieces of this much device
# time, requests answered in between (its devices have their own clocks; nothing is dropped).
TIMED_PIECE_S = 0.02
# ... with a real sleep between pieces: a queued request needs loop iterations to be answered.
CATCH_UP_YIELD_S = 0.001
_SILENT_MAX_S = 30.0                    # a silent device answers eventually, so stop() ends
_READ_FC = {Function.HOLDING: 3, Function.INPUT: 4}
log = logging.getLogger(__name__)


def _put(registers: dict[int, int], address: int, values: list[int]) -> None:
    registers.update(zip(range(address, address + len(values)), values))


class Emulator:
    """The register-level behaviour of the bench; serve it with `serve()`."""

    def __init__(self, loadcell_map: LoadCellMap, servo_map: ServoMap, plant: Plant | None = None,
                 *, noise_N: float = 0.01, seed: int | None = None, preload_N: float = -0.3,
                 capacity_N: float = LOADCELL_CAPACITY_N, max_advance_s: float = 0.5,
                 lag_limit_s: float = LAG_LIMIT_S, conversion_s: float = CONVERSION_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.loadcell_map, self.servo_map = loadcell_map, servo_map
        self.plant: Plant = plant if plant is not None else FlatPlatePlant()
        self.noise_N, self.preload_N, self.capacity_N = noise_N, preload_N, capacity_N
        # An idle emulator does not integrate hours of plant time on the next request.
        self.max_advance_s = max_advance_s
        self.lag_limit_s = lag_limit_s
        self.lag_events = 0
        self.worst_lag_s = 0.0
        self._lag_unread = {"loadcell": False, "servo": False}   # latched until the status is read
        self.rng = random.Random(seed)
        # The emulated devices' own clock (monotonic seconds); a test may drive it by hand.
        self.clock = clock
        self.lock = threading.Lock()
        self.tare_N = 0.0
        self._plant_time_s = 0.0      # time the plant was advanced by
        impulse_Ns = getattr(self.plant, "impulse_Ns", None)
        self._converter = None if impulse_Ns is None else IntegratingConverter(0.0, impulse_Ns, conversion_s)
        self.servo_enabled = servo_map.enable is None
        self.servo_setpoint_rad: float | None = None
        # One boot id per device: behind a gateway each transmitter restarts on its own.
        self.sessions = {"loadcell": BootSession(self.rng, clock),
                         "servo": BootSession(self.rng, clock)}
        self.watchdog = CommandWatchdog(clock)
        self.rest = RestWatch()
        self.requests = 0
        self.plant_resets = 0
        self.log = RateLimitedLog()
        self._faults: dict[str, str] = {}
        self._t_mono: float | None = None
        self._rate_rad_s = 0.0        # measured across requests: the Plant protocol has no rate
        self._registers = {LOADCELL_UNIT: {"holding": {}, "input": {}},
                           SERVO_UNIT: {"holding": {}, "input": {}}}
        self.timed = TimedFirmware(self)
        sp = servo_map.setpoint
        lo, hi = SERVO_RANGE_RAD
        self.setpoint_range_rad = (lo if sp.min is None else sp.min * sp.to_si,
                                   hi if sp.max is None else sp.max * sp.to_si)

    def inject(self, device: str, fault: str | None) -> None:
        """Make 'loadcell' or 'servo' misbehave: one of FAULTS, or None to heal it."""
        if device not in ("loadcell", "servo") or (fault is not None and fault not in FAULTS):
            raise ValueError(f"inject({device!r}, {fault!r}): device is 'loadcell' or 'servo', "
                             f"fault one of {FAULTS} or None")
        with self.lock:
            if fault is None:
                self._faults.pop(device, None)
            else:
                self._faults[device] = fault

    def tick_interval_s(self) -> float:
        """How often `serve` ticks: TICK_S while the plant moves, seldom once it rests (the
        watchdog, if armed, is checked at a tenth of a second)."""
        if self.timed.active:   # catch up at once, letting requests through between pieces
            return CATCH_UP_YIELD_S if self.clock() - (self._t_mono or 0.0) > TICK_S else TICK_S
        if not self.rest.resting:
            return TICK_S
        return IDLE_WATCHDOG_TICK_S if self.watchdog.timeout_s and not self.watchdog.tripped \
            else IDLE_TICK_S

    def reboot(self, device: str) -> None:
        """Restart 'loadcell' or 'servo' behind the gateway, sockets kept: a new boot id, the
        uptime from zero, the registers cleared; the load cell forgets its tare, the servo its
        enable, its setpoint and its watchdog, and the feather comes to rest."""
        if device not in self.sessions:
            raise ValueError(f"reboot({device!r}): device is 'loadcell' or 'servo'")
        with self.lock:
            self.sessions[device].boot()
            unit = LOADCELL_UNIT if device == "loadcell" else SERVO_UNIT
            self._registers[unit] = {"holding": {}, "input": {}}
            self.timed.reboot(device)
            if device == "loadcell":
                self.tare_N = 0.0
            else:
                self.servo_enabled = self.servo_map.enable is None
                self.watchdog.arm(0)
                self._reset_plant(None)
            self.log(logging.WARNING, f"{device} rebooted (boot id {self.sessions[device].id}); "
                                      "connections kept")

    def _put_session(self, registers: dict[int, int], field: SessionField | None,
                     device: str) -> None:
        if field is not None:
            boot_id, uptime = self.sessions[device].words()
            _put(registers, field.address, [boot_id])
            _put(registers, field.uptime_address, uptime)

    def _check_watchdog(self) -> None:
        """The servo firmware's watchdog (called with the lock held): no request for its
        timeout, and the servo goes to its safe position until the next setpoint."""
        if self.watchdog.expired():
            self.rest.disturb()
            self.timed.player.abort()
            lo, hi = self.setpoint_range_rad
            self.servo_setpoint_rad = min(max(0.0, lo), hi)
            self.plant.set_setpoint_rad(self.servo_setpoint_rad)
            sp = self.servo_map.setpoint
            _put(self._registers[SERVO_UNIT]["holding"], sp.address,
                 encode_value(sp, self.servo_setpoint_rad / sp.to_si))
            self.log(logging.WARNING, f"servo watchdog: no request for {self.watchdog.timeout_s} s;"
                                      f" safe position (trip #{self.watchdog.trips})")

    def units(self) -> dict[int, tuple]:
        """Unit id -> (register spaces, handler), for featherstar.hil.modbus_server."""
        lc, sv = self.loadcell_map, self.servo_map
        lc_read = lc.value.spans() + ([(lc.status.address, 1)] if lc.status else []) \
            + (lc.session.spans() if lc.session else [])
        lc_write = [(lc.tare.address, 1)] if lc.tare else []
        sv_read = (sv.position.spans() if sv.position else []) \
            + ([(sv.status.address, 1)] if sv.status else []) \
            + (sv.session.spans() if sv.session else [])
        sv_write = [(sv.setpoint.address, 2)] + ([(sv.enable.address, 1)] if sv.enable else []) \
            + ([(sv.watchdog.address, 1)] if sv.watchdog else [])
        for m, read, write in ((lc, lc_read, lc_write), (sv, sv_read, sv_write)):
            for _space, _name, address, count, writable in m.timed.spans(m.read_function.value):
                (write if writable else read).append((address, count))
        return {LOADCELL_UNIT: (spaces_for(lc.read_function.value, lc_read, lc_write),
                                self._loadcell_action),
                SERVO_UNIT: (spaces_for(sv.read_function.value, sv_read, sv_write),
                             self._servo_action)}

    def force_N(self) -> float:
        """What the cell feels, before tare and noise."""
        return self.plant.thrust_N + self.preload_N

    def converted_force_N(self) -> float:
        """What a reading reports, before tare and noise: the integrating converter's mean force
        (the instantaneous force for a plant without `impulse_Ns`)."""
        if self._converter is None:
            return self.force_N()
        return self._converter.read(self.plant.thrust_N) + self.preload_N

    def _advance(self) -> bool:
        """Advance the plant to now (a request); False (after resetting it) if its step failed."""
        self.requests += 1
        if self.timed.active:
            # Device-timed: the registers answer at once (clock, log head, player state); the
            # plant catches up piece by piece in the ticks, as a device's own CPU would run it.
            return True
        return self._advance_plant()

    def tick(self, due_s: float | None = None) -> None:
        """Keep plant time with the wall clock while no request does (called every TICK_S by
        `serve`); `due_s`: when this tick was due (time.monotonic()). It is late when the event
        loop was held up, or when the lock was (a request, fault injection)."""
        with self.lock:
            late_s = 0.0 if due_s is None else time.monotonic() - due_s
            if late_s > self.lag_limit_s:
                self._behind(late_s, "the event loop was held up (process not scheduled?)")
            if self._t_mono is None or self.clock() - self._t_mono >= TICK_S \
                    or self.timed.active:
                self._advance_plant()
            # A tick that comes late finds the client's commands still queued in the socket:
            # the silence is the emulator's own, not the client's (real firmware takes its
            # frames by interrupt). The next tick, after the queue, decides.
            # Catching up a device-timed plant likewise leaves the commands queued: judged
            # once the plant has caught up with the clock.
            if late_s <= WATCHDOG_LATE_S and self.clock() - (self._t_mono or 0.0) <= TICK_S:
                self._check_watchdog()

    def _advance_plant(self) -> bool:
        now, wall0_s = self.clock(), time.perf_counter()
        if self._t_mono is not None and now > self._t_mono:
            if self.rest.resting and not self.timed.active:
                # Still for a second: integrating it would change nothing the registers show.
                self._plant_time_s += now - self._t_mono
                if self._converter is not None:
                    self._converter.note(self._plant_time_s, self.plant.impulse_Ns)
                self._t_mono = now
                return True
            # Device time is never dropped while a trajectory plays or a log runs: the plant
            # is advanced a piece per tick and may lag the clock (the samples carry their time).
            timed = self.timed.active
            cap_s = TIMED_PIECE_S if timed else self.max_advance_s
            angle_rad, dt_s = self.plant.angle_rad, min(now - self._t_mono, cap_s)
            try:
                if timed:
                    self.timed.advance(self._t_mono, dt_s)
                    self._t_mono += dt_s
                    self._rate_rad_s = (self.plant.angle_rad - angle_rad) / dt_s
                    return True
                self.step_plant(dt_s)
                if not (math.isfinite(self.plant.angle_rad) and math.isfinite(self.plant.thrust_N)):
                    raise HILError(f"plant state not finite (angle {self.plant.angle_rad})")
            except Exception as exc:   # one bad step must not poison the device for good
                self._reset_plant(exc)
                self._t_mono = now
                return False
            self._rate_rad_s = (self.plant.angle_rad - angle_rad) / dt_s
            self.rest.note(dt_s, self._rate_rad_s, self.plant.thrust_N)
            if (dropped_s := now - self._t_mono - dt_s) > self.lag_limit_s:
                self._behind(dropped_s, f"{dropped_s:.3f} s of plant time dropped (max_advance_s)")
            if (compute_s := time.perf_counter() - wall0_s) > self.lag_limit_s:
                self._behind(compute_s, f"advancing the plant {dt_s * 1e3:.1f} ms took {compute_s * 1e3:.1f} ms")
        self._t_mono = now
        return True

    def step_plant(self, dt_s: float) -> None:
        """Advance the plant by dt_s at its current setpoint (the converter notes the impulse)."""
        self.plant.advance(dt_s)
        self._plant_time_s += dt_s
        if self._converter is not None:
            self._converter.note(self._plant_time_s, self.plant.impulse_Ns)

    def loadcell_unit_registers(self) -> dict[int, int]:
        return self._registers[LOADCELL_UNIT][self.loadcell_map.read_function.value]

    def servo_unit_registers(self) -> dict[int, int]:
        return self._registers[SERVO_UNIT][self.servo_map.read_function.value]

    def _behind(self, lag_s: float, why: str) -> None:
        self.lag_events += 1
        self.worst_lag_s = max(self.worst_lag_s, lag_s)
        self._lag_unread = dict.fromkeys(self._lag_unread, True)
        self.log(logging.WARNING, f"plant behind real time by {lag_s * 1e3:.0f} ms: {why} "
                                  f"(lag bit set; event #{self.lag_events})")

    def _reset_plant(self, exc: Exception | None) -> None:
        """Back to rest: after a failed step (exc), or a servo reboot (None)."""
        self.rest.disturb()
        if exc is not None:
            self.plant_resets += 1
            self.log(logging.ERROR, f"plant step failed ({type(exc).__name__}: {exc}); plant "
                                    f"reset to rest, servo disabled until a new setpoint "
                                    f"(reset #{self.plant_resets})")
        reset = getattr(self.plant, "reset", None)
        if reset is not None:
            reset()
        if self._converter is not None:
            self._converter.reset(self._plant_time_s, self.plant.impulse_Ns)
        self.servo_setpoint_rad = None
        self._rate_rad_s = 0.0

    async def _misbehave(self, device: str) -> int | None:
        if self._faults.get(device) == "silent":
            t_end = time.monotonic() + _SILENT_MAX_S
            while self._faults.get(device) == "silent" and time.monotonic() < t_end:
                await asyncio.sleep(0.005)
        if self._faults.get(device) == "exception":
            return DEVICE_FAILURE
        return None

    def _status(self, field: StatusField, device: str, overload: bool, address: int, count: int) -> list[int]:
        """The status word; a lag report is cleared only when this read returns the word."""
        status = Status(stable=abs(self._rate_rad_s) < _STABLE_RATE_RAD_S,
                        overload=overload or self._faults.get(device) == "overload",
                        error=self._faults.get(device) == "error", lagging=self._lag_unread[device])
        if address <= field.address < address + count:
            self._lag_unread[device] = False
        return [encode_status(field, status)]

    @staticmethod
    def _put_number(registers: dict[int, int], field: NumberField, x: float) -> None:
        decimals = None
        if field.decimals_address is not None:
            decimals = REGISTER_DECIMALS
            _put(registers, field.decimals_address, [decimals])
        _put(registers, field.address, encode_value(field, x, decimals))

    @staticmethod
    def _read(registers: dict[int, int], address: int, count: int) -> list[int]:
        return [registers.get(a, 0) for a in range(address, address + count)]

    async def _loadcell_action(self, function_code: int, space: str, address: int, count: int,
                               values: list[int] | None) -> list[int] | int | None:
        if (exc := await self._misbehave("loadcell")) is not None:
            return exc
        m = self.loadcell_map
        registers = self._registers[LOADCELL_UNIT][space]
        with self.lock:
            if not self._advance():
                return DEVICE_FAILURE
            if values is not None:
                if m.tare and address <= m.tare.address < address + count \
                        and values[m.tare.address - address] == m.tare.value:
                    self.tare_N = self.converted_force_N()
                _put(registers, address, values)
                return self.timed.on_write("loadcell", registers, address, count)
            if function_code == _READ_FC[m.read_function] and \
                    self._faults.get("loadcell") != "freeze":
                force_N = self.converted_force_N()
                reading_N = force_N - self.tare_N + self.rng.gauss(0.0, self.noise_N)
                self._put_number(registers, m.value, reading_N / m.value.to_si)
                if m.status is not None:
                    _put(registers, m.status.address,
                         self._status(m.status, "loadcell", abs(force_N) > self.capacity_N, address, count))
            if function_code == _READ_FC[m.read_function]:
                self._put_session(registers, m.session, "loadcell")
                self.timed.fill_reads("loadcell", registers)
            return self._read(registers, address, count)

    async def _servo_action(self, function_code: int, space: str, address: int, count: int,
                            values: list[int] | None) -> list[int] | int | None:
        if (exc := await self._misbehave("servo")) is not None:
            return exc
        m = self.servo_map
        registers = self._registers[SERVO_UNIT][space]
        with self.lock:
            if not self._advance():
                return DEVICE_FAILURE
            if values is not None:
                self.watchdog.feed()     # a command; a monitor that only reads does not feed it
                return self._servo_write(registers, address, values)
            if function_code == _READ_FC[m.read_function] and \
                    self._faults.get("servo") != "freeze":
                if m.position is not None:
                    self._put_number(registers, m.position,
                                     self.plant.angle_rad / m.position.to_si)
                if m.status is not None:
                    _put(registers, m.status.address, self._status(m.status, "servo", False, address, count))
            if function_code == _READ_FC[m.read_function]:
                self._put_session(registers, m.session, "servo")
                self.timed.fill_reads("servo", registers)
            return self._read(registers, address, count)

    def _servo_write(self, registers: dict[int, int], address: int,
                     values: list[int]) -> int | None:
        m = self.servo_map
        self.rest.disturb()      # a setpoint, an enable or a stroke may move the plant
        end = address + len(values)
        sp = m.setpoint
        setpoint_rad = None
        if address < sp.address + 2 and sp.address < end:
            if not (address <= sp.address and sp.address + 2 <= end):
                return ILLEGAL_ADDRESS      # half a 32-bit setpoint
            offset = sp.address - address
            value = decode_value(sp, values[offset:offset + 2])
            if not math.isfinite(value):
                return ILLEGAL_VALUE        # NaN / inf: refused, nothing is changed
            lo, hi = self.setpoint_range_rad
            # A real controller saturates at its travel; it does not follow 9000 degrees.
            setpoint_rad = min(max(value * sp.to_si, lo), hi)
            values = list(values)
            values[offset:offset + 2] = encode_value(sp, setpoint_rad / sp.to_si)
        _put(registers, address, values)
        if setpoint_rad is not None:   # the client takes over: a playing stroke stops
            self.servo_setpoint_rad = setpoint_rad
            self.watchdog.resume()
            self.timed.player.abort()
        if m.enable is not None and address <= m.enable.address < end:
            self.servo_enabled = values[m.enable.address - address] == m.enable.value
        if m.watchdog is not None and address <= m.watchdog.address < end:
            self.watchdog.arm(values[m.watchdog.address - address])
        if (refused := self.timed.on_write("servo", registers, address, len(values))) is not None:
            return refused
        if self.servo_enabled and self.servo_setpoint_rad is not None:
            self.plant.set_setpoint_rad(self.servo_setpoint_rad)
        return None
