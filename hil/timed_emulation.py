"""Device-timed firmware of the emulated bench: the servo's trajectory player and both devices'
sample logs behind their registers (featherstar.hil.timed_registers), advanced with the plant.

`TimedFirmware.advance(t0, dt)` replaces the emulator's one-piece plant advance while a
trajectory plays or a log runs: the plant goes from event to event (a trajectory sample
switching, a log sample due), so setpoints and samples fall at their device-clock times
however late the emulator process got the CPU. A log sample of the integrating load cell is the
mean force over its period (the impulse difference), as a sigma-delta transmitter reports.
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
    def _next_event_mono(self, t_mono: float) -> float:
        times = [self.mono_s("servo", self.player.next_switch_s(self.device_s("servo", t_mono)))]
        for device, log in self.logs.items():
            if log is not None:
                times.append(self.mono_s(device, log.next_due_s()))
        return min(times)

    def advance(self, t0_mono: float, dt_s: float) -> None:
        """Advance the plant from wall time t0_mono by dt_s through every event on the way."""
        emu, t, t_end = self.emu, t0_mono, t0_mono + dt_s
        while t < t_end:
            setpoint = self.player.setpoint_rad(self.device_s("servo", t))
            if setpoint is not None and emu.servo_enabled:
                emu.plant.set_setpoint_rad(setpoint)
            nxt = min(t_end, max(self._next_event_mono(t), t + 1e-7))
            emu.step_plant(nxt - t)
            t = nxt
            self._record_due(t)

    def _record_due(self, t_mono: float) -> None:
        for device, log in self.logs.items():
            if log is None or log.period_s is None:
                continue
            while self.mono_s(device, log.next_due_s()) <= t_mono + 1e-9:
                t_dev = log.next_due_s()
                log.head += 1
                self._put_entry(device, log, t_dev)

    def _put_entry(self, device: str, log: SampleLog, t_dev_s: float) -> None:
        emu = self.emu
        if device == "loadcell":
            field, unit = emu.loadcell_map.value, emu.loadcell_unit_registers()
            impulse = getattr(emu.plant, "impulse_Ns", None)
            if impulse is None:
                force_N = emu.plant.thrust_N
            else:
                force_N = (impulse - self._impulse_at_sample_Ns) / log.period_s
                self._impulse_at_sample_Ns = impulse
            value = (force_N + emu.preload_N - emu.tare_N + emu.rng.gauss(0.0, emu.noise_N))
            table = emu.loadcell_map.timed.log
        else:
            field, unit = emu.servo_map.position, emu.servo_unit_registers()
            value, table = emu.plant.angle_rad, emu.servo_map.timed.log
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
