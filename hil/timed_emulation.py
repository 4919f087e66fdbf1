"""Device-timed firmware of the emulated bench: the servo's trajectory player and both devices'
sample logs behind their registers (featherstar.hil.timed_registers), advanced with the plant.

`TimedFirmware.advance(t0, dt)` replaces the emulator's one-piece plant advance while a
trajectory plays or a log runs: the plant goes from one trajectory sample switch to the next,
so setpoints fall at their device-clock times however late the emulator process got the CPU.
Log samples due inside a piece are taken from the states at its ends, linearly interpolated
(the impulse is the integral of the thrust: smooth), which costs no extra plant step. A sample
of the integrating load cell is the mean force over its period (the impulse difference), as a
sigma-delta transmitter reports.
"""
from __future__ import annotations

import math
import struct
from typing import Any

from .codec import encode_value
from .modbus_server import ILLEGAL_VALUE
from .timed_device import SampleLog, TrajectoryPlayer
from .timed_registers import ENTRY_REGISTERS, PlayerState

_WRAP_US = 1 << 32


def _words32(x: int) -> list[int]:
    x %= _WRAP_US
    return [x >> 16, x & 0xFFFF]


class TimedFirmware:
    """The timed tables of both devices of one emulator (only those their maps declare)."""

    def __init__(self, emulator: Any) -> None:
        # `emulator`: the featherstar.hil.emulator.Emulator that owns this firmware (not
        # imported: it imports this module).
        self.emu = emulator
        self.player = TrajectoryPlayer()
        lc_log, sv_log = emulator.loadcell_map.timed.log, emulator.servo_map.timed.log
        self.logs = {"loadcell": SampleLog(lc_log.capacity) if lc_log else None,
                     "servo": SampleLog(sv_log.capacity) if sv_log else None}
        self._impulse_at_sample_Ns = 0.0

    # --- clocks: each device counts from its own boot ------------------------------------
    def device_s(self, device: str, mono_s: float) -> float:
        return mono_s - self.emu.sessions[device].boot_s

    def mono_s(self, device: str, device_s: float) -> float:
        return device_s + self.emu.sessions[device].boot_s

    @property
    def active(self) -> bool:
        """A trajectory armed or playing, or a log running: device time must not be dropped."""
        state = self.player.state(self.device_s("servo", self.emu.clock()))
        return state in (PlayerState.ARMED, PlayerState.PLAYING) \
            or any(log is not None and log.period_s is not None for log in self.logs.values())

    def reboot(self, device: str) -> None:
        if device == "servo":
            self.player.abort()
        if self.logs[device] is not None:
            self.logs[device].restart(None, 0.0)

    # --- the plant, from event to event --------------------------------------------------
    def advance(self, t0_mono: float, dt_s: float) -> None:
        """Advance the plant from wall time t0_mono by dt_s, a piece per trajectory sample."""
        emu, t, t_end = self.emu, t0_mono, t0_mono + dt_s
        while t < t_end:
            setpoint = self.player.setpoint_rad(self.device_s("servo", t))
            if setpoint is not None and emu.servo_enabled:
                emu.plant.set_setpoint_rad(setpoint)
            switch = self.mono_s("servo", self.player.next_switch_s(self.device_s("servo", t)))
            # Pieces no longer than a log period: a sample interpolates within one piece only.
            nxt = min(t_end, max(switch, t + 1e-7), t + self._max_piece_s())
            before = self._state()
            emu.step_plant(nxt - t)
            self._record_due(t, before, nxt, self._state())
            t = nxt

    def _max_piece_s(self) -> float:
        periods = [log.period_s for log in self.logs.values()
                   if log is not None and log.period_s is not None]
        return min(periods, default=math.inf)

    def _state(self) -> tuple[float, float]:
        """(impulse or thrust, angle) of the plant now."""
        plant = self.emu.plant
        return getattr(plant, "impulse_Ns", plant.thrust_N), plant.angle_rad

    def _record_due(self, t_a: float, state_a: tuple[float, float], t_b: float,
                    state_b: tuple[float, float]) -> None:
        """Take the samples due in (t_a, t_b], interpolating the plant's state."""
        for device, log in self.logs.items():
            if log is None or log.period_s is None:
                continue
            while (t := self.mono_s(device, log.next_due_s())) <= t_b + 1e-9:
                w = 0.0 if t_b <= t_a else min(max((t - t_a) / (t_b - t_a), 0.0), 1.0)
                state = tuple(a + w * (b - a) for a, b in zip(state_a, state_b))
                t_dev = log.next_due_s()
                log.head += 1
                self._put_entry(device, log, t_dev, state)

    def _put_entry(self, device: str, log: SampleLog, t_dev_s: float,
                   state: tuple[float, float]) -> None:
        emu = self.emu
        if device == "loadcell":
            field, unit = emu.loadcell_map.value, emu.loadcell_unit_registers()
            if getattr(emu.plant, "impulse_Ns", None) is None:
                force_N = state[0]
            else:
                force_N = (state[0] - self._impulse_at_sample_Ns) / log.period_s
                self._impulse_at_sample_Ns = state[0]
            value = (force_N + emu.preload_N - emu.tare_N + emu.rng.gauss(0.0, emu.noise_N))
            table = emu.loadcell_map.timed.log
        else:
            field, unit = emu.servo_map.position, emu.servo_unit_registers()
            value, table = state[1], emu.servo_map.timed.log
        words = _words32(round(t_dev_s * 1e6)) + encode_value(field, value / field.to_si)
        address = table.entry_address(log.head - 1)
        unit.update(zip(range(address, address + ENTRY_REGISTERS), words))

    # --- registers ------------------------------------------------------------------------
    def fill_reads(self, device: str, registers: dict[int, int]) -> None:
        """Clock, player state and log head, as of now, before a read is answered."""
        m = self.emu.loadcell_map if device == "loadcell" else self.emu.servo_map
        if m.timed.clock is None:
            return
        now_dev = self.device_s(device, self.emu.clock())
        registers.update(zip((m.timed.clock.address, m.timed.clock.address + 1),
                             _words32(round(now_dev * 1e6))))
        if m.timed.trajectory is not None:
            registers[m.timed.trajectory.state_address] = int(self.player.state(now_dev))
        if m.timed.log is not None:
            registers.update(zip((m.timed.log.head_address, m.timed.log.head_address + 1),
                                 _words32(self.logs[device].head)))

    def on_write(self, device: str, registers: dict[int, int], address: int,
                 count: int) -> int | None:
        """Act on a write that touched a timed table (registers already hold the values)."""
        m = self.emu.loadcell_map if device == "loadcell" else self.emu.servo_map
        end = address + count
        now_dev = self.device_s(device, self.emu.clock())
        if (log := m.timed.log) is not None and address <= log.period_us_address < end:
            period_us = registers[log.period_us_address]
            if device == "loadcell":
                self._impulse_at_sample_Ns = getattr(self.emu.plant, "impulse_Ns", 0.0)
            self.logs[device].restart(period_us / 1e6 if period_us else None, now_dev)
        traj = m.timed.trajectory
        if traj is not None and address <= traj.start_address + 1 and traj.start_address < end:
            period_us = registers.get(traj.period_us_address, 0)
            n = registers.get(traj.count_address, 0)
            if not (period_us > 0 and 1 <= n <= traj.capacity):
                return ILLEGAL_VALUE
            hi, lo = registers.get(traj.start_address, 0), registers.get(traj.start_address + 1, 0)
            ahead_us = (((hi << 16) | lo) - round(now_dev * 1e6)) % _WRAP_US
            if ahead_us >= _WRAP_US // 2:
                ahead_us -= _WRAP_US      # a start in the past plays from where it would be
            raw = [registers.get(traj.data_address + k, 0) for k in range(n)]
            counts = struct.unpack(f">{n}h", struct.pack(f">{n}H", *raw))
            to_rad = self.emu.servo_map.setpoint.to_si / 10 ** traj.decimals
            lo_rad, hi_rad = self.emu.setpoint_range_rad
            samples = [min(max(c * to_rad, lo_rad), hi_rad) for c in counts]
            if not all(math.isfinite(x) for x in samples):
                return ILLEGAL_VALUE
            self.player.arm(period_us / 1e6, samples, now_dev + ahead_us / 1e6)
        return None
