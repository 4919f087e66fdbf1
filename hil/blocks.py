"""Hardware blocks: a Modbus load cell and a Modbus servo behind the cosim Block protocol.

Both offer the same ports as their simulated counterparts, so a scene swaps one for the other.
Constructor arguments are plain scalars and strings, so the master can build them from a scene
table: `LoadCell(**table)`.

Timing: `do_step(t_s, h_s)` does the I/O (the servo writes its setpoint and reads back, the load
cell reads); `get_outputs()` returns what the last `start`/`do_step` read and never touches the
bus, so the master may call it as often as it likes. With a wall-clock pacer (`featherstar.hil.pacing`),
the values read in the step that ends at t_s are the state of the bench at t_s.
"""
from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import Mapping

from ..cosim.framework.block import Port
from .codec import decode_status, encode_value
from .device import ModbusDevice, ReadPlan, field_value
from .errors import Fault, HILConfigError, HILError
from .link import FaultSignal
from .registers import Status, load_loadcell_map, load_servo_map
from .session import SessionWatch

log = logging.getLogger(__name__)

MG996R_LIMITS_RAD = (-math.pi / 2, math.pi / 2)
MG996R_RATE_RAD_S = 6.2      # 0.17 s / 60 deg at 4.8 V
_SAFE_RETRY_PAUSE_S = 0.05   # between safe-position attempts: a rebooting device needs time


def _session_and_read_plan(device_map, spans: list[tuple[int, int]]) -> tuple[SessionWatch | None, ReadPlan]:
    """The registers a device block reads every cycle: its own `spans`, the status register and
    the session registers when the map has them, in one read plan; and the watch of the session."""
    spans = list(spans)
    if device_map.status is not None:
        spans.append((device_map.status.address, 1))
    session = None if device_map.session is None else SessionWatch(device_map.session)
    if device_map.session is not None:
        spans += device_map.session.spans()
    return session, ReadPlan.build(device_map.read_function, spans)


class LoadCell(ModbusDevice):
    """A load-cell transmitter; output `thrust_N`, the tared reading in N, positive up.

    stale_s: a value that does not change for this long is a STALE fault (a live load cell
    flickers in its last digit; a frozen transmitter or a stuck gateway repeats itself). The
    2 s default leaves room for a heavily filtered transmitter reading a feather at rest; None
    disables the check. unstable_s: the transmitter's "stable" bit clear for this long is
    a STALE fault; None (default) because a flapping feather keeps the cell in motion.
    tare_on_start: command a tare in start() (the feather must be at rest).

    After a reconnect the tare is unknown: a transmitter that rebooted has forgotten it, and the
    feather is moving, so it cannot be tared again. The "reconnect" event then carries
    `tare_unknown`, and the master excludes every period from that time on (featherstar.cosim.swimmer.validity).
    """

    def __init__(self, name: str, url: str, map: str | Path = "loadcell-float32-abcd", *,
                 timeout_s: float = 0.05, reconnect_s: float | None = None,
                 stale_s: float | None = 2.0, unstable_s: float | None = None,
                 tare_on_start: bool = True, start_timeout_s: float = 1.0,
                 start_retry_s: float = 5.0, warning: str | None = None) -> None:
        super().__init__(name, url, timeout_s=timeout_s, reconnect_s=reconnect_s,
                         start_timeout_s=start_timeout_s, start_retry_s=start_retry_s)
        # What the run's summary must say about this measurement (e.g. nothing real drives it).
        self.warnings: list[str] = [warning] if warning else []
        self.map = load_loadcell_map(map)
        if tare_on_start and self.map.tare is None:
            raise HILConfigError(f"{name}: register map {self.map.source} has no [tare]; "
                                 "pass tare_on_start=False")
        for label, value in (("stale_s", stale_s), ("unstable_s", unstable_s)):
            if value is not None and not value > 0:
                raise HILConfigError(f"{name}: {label} must be positive or None, got {value}")
        self.stale_s = stale_s
        self.unstable_s = unstable_s
        self.tare_on_start = tare_on_start
        self.inputs: Mapping[str, Port] = {}
        self.outputs: Mapping[str, Port] = {
            "thrust_N": Port("thrust_N", "N", "tared load-cell reading, positive up"),
            "t_read_s": Port("t_read_s", "s", "run time at which the reading was taken, on the "
                                              "PC's clock (its most punctual read so far on time)")}
        self._session, self._plan = _session_and_read_plan(self.map, self.map.value.spans())
        self.status = Status()
        self._thrust_N = math.nan
        self._last_raw: tuple[int, ...] | None = None
        self._last_change_mono = self._last_stable_mono = 0.0
        self._read_mono = math.nan           # PC clock at the last reading
        self._mono_at_t0: float | None = None  # PC clock that run time 0 corresponds to
        self._t_read_s = math.nan

    def start(self, t0_s: float) -> None:
        self._open()
        self._started = True
        with self._patient_start():
            if self.tare_on_start:
                self.tare(t0_s)
            self._last_change_mono = self._last_stable_mono = time.monotonic()
            self._guard(t0_s, self._sample)
        self._mono_at_t0, self._t_read_s = None, t0_s   # anchored by the paced steps (do_step)

    def _on_reconnect(self, t_s: float) -> None:
        self._note(t_s, "reconnect", f"new connection to {self.link.where}: the transmitter may "
                                     "have rebooted and lost its tare", tare_unknown=True)

    def set_inputs(self, values: Mapping[str, float]) -> None:
        if values:
            raise HILError(f"{self.name}: a load cell has no inputs, got {sorted(values)}")

    def get_outputs(self) -> dict[str, float]:
        self._check_started()
        return {"thrust_N": self._thrust_N, "t_read_s": self._t_read_s}

    def do_step(self, t_s: float, h_s: float) -> None:
        self._check_started()
        self._guard(t_s + h_s, self._sample)
        # Run time 0 on the PC's clock, from the most punctual read so far: a paced step never
        # starts early, so the read least behind its step's time is the one on time. (Anchored on
        # the first read alone, a first read 11 ms late under load stamped every later sample 11 ms
        # early, and the record ended short of the run.)
        offset_s = self._read_mono - (t_s + h_s)
        if self._mono_at_t0 is None or offset_s < self._mono_at_t0:
            self._mono_at_t0 = offset_s
        self._t_read_s = self._read_mono - self._mono_at_t0
        self._note_lag(t_s + h_s, self.status)
        # A transmitter that restarted has lost its tare, and the feather moves: no new one.
        self._note_restart(t_s + h_s, tare_unknown=True)

    def close(self) -> None:
        self._started = False
        self._release()

    def tare(self, t_s: float = 0.0) -> None:
        """Zero the transmitter now (the feather must be at rest)."""
        if self.map.tare is None:
            raise HILConfigError(f"{self.name}: register map {self.map.source} has no [tare]")
        self._check_started()
        tare = self.map.tare
        self._guard(t_s, lambda: self.link.write_one(tare.address, tare.value, self.url.unit))

    def _sample(self) -> None:
        regs = self._plan.read(self.link, self.url.unit)
        now = self._read_mono = time.monotonic()
        if self.map.status is not None:
            status = self.status = decode_status(self.map.status, regs[self.map.status.address])
            if status.error:
                raise FaultSignal(Fault.DEVICE_ERROR, "transmitter error bit set")
            if status.overload:
                raise FaultSignal(Fault.OVERLOAD, "transmitter overload bit set")
            if status.stable:
                self._last_stable_mono = now
            elif self.unstable_s is not None and now - self._last_stable_mono > self.unstable_s:
                raise FaultSignal(Fault.STALE, f"not stable for {now - self._last_stable_mono:.3f}"
                                               f" s (unstable_s={self.unstable_s})")
        if self._session is not None:
            self._restart = self._session.check(regs, now) or self._restart
        f = self.map.value
        value = field_value(f, regs)
        raw = (regs[f.address], regs[f.address + 1], regs.get(f.decimals_address))
        if raw != self._last_raw:
            self._last_raw, self._last_change_mono = raw, now
        elif self.stale_s is not None and now - self._last_change_mono > self.stale_s:
            raise FaultSignal(Fault.STALE, f"value frozen at {value:g} {f.unit} for "
                                           f"{now - self._last_change_mono:.3f} s "
                                           f"(stale_s={self.stale_s})")
        self._thrust_N = value * f.to_si


class Servo(ModbusDevice):
    """A position servo; input `setpoint_rad`, outputs `angle_rad`, `rate_rad_s`, `accel_rad_s2`.

    Setpoints are clamped to `limits_rad` (intersected with the map's setpoint range) and to
    `rate_limit_rad_s`, per step, before they are sent. When the map has a [position] read-back,
    angle is the read-back and rate/accel are backward differences over the read times
    (`estimate_source == "readback"`; they carry the read-back's quantisation noise amplified by
    1/dt and 1/dt^2). Without read-back, angle is the commanded (clamped, rate-limited) setpoint
    and rate/accel are its differences over h_s (`estimate_source == "setpoint"`), which assumes
    the servo keeps up; start() then commands `safe_rad`, the only position it can assume.
    A [status] error bit is a DEVICE_ERROR fault.

    `close()` commands `safe_rad` and never raises: on a fresh connection (a stop may interrupt
    a request half-way), retried until `safe_timeout_s` has passed, because a stalled or
    rebooting device may come back. `safe_confirmed` says whether the device acknowledged it.
    """

    def __init__(self, name: str, url: str, map: str | Path = "servo-default", *,
                 timeout_s: float = 0.05, reconnect_s: float | None = None,
                 limits_rad: tuple[float, float] = MG996R_LIMITS_RAD,
                 rate_limit_rad_s: float = MG996R_RATE_RAD_S, safe_rad: float = 0.0,
                 safe_timeout_s: float = 5.0, start_timeout_s: float = 1.0,
                 start_retry_s: float = 5.0) -> None:
        super().__init__(name, url, timeout_s=timeout_s, reconnect_s=reconnect_s,
                         start_timeout_s=start_timeout_s, start_retry_s=start_retry_s)
        if not (isinstance(safe_timeout_s, (int, float)) and math.isfinite(safe_timeout_s)
                and safe_timeout_s > 0):
            raise HILConfigError(f"{name}: safe_timeout_s must be positive, got {safe_timeout_s!r}")
        self.safe_timeout_s = float(safe_timeout_s)
        self.safe_confirmed: bool | None = None
        self.map = load_servo_map(map)
        sp = self.map.setpoint
        lo, hi = float(limits_rad[0]), float(limits_rad[1])
        if sp.min is not None:
            lo = max(lo, sp.min * sp.to_si)
        if sp.max is not None:
            hi = min(hi, sp.max * sp.to_si)
        if not lo < hi:
            raise HILConfigError(f"{name}: limits_rad {limits_rad} leave no range within the "
                                 f"map's setpoint range [{sp.min}, {sp.max}] {sp.unit}")
        if not lo <= safe_rad <= hi:
            raise HILConfigError(f"{name}: safe_rad={safe_rad} outside limits [{lo}, {hi}] rad")
        if not rate_limit_rad_s > 0:
            raise HILConfigError(f"{name}: rate_limit_rad_s must be positive")
        self.limits_rad = (lo, hi)
        self.rate_limit_rad_s = rate_limit_rad_s
        self.safe_rad = safe_rad
        self.estimate_source = "readback" if self.map.position is not None else "setpoint"
        self.inputs: Mapping[str, Port] = {
            "setpoint_rad": Port("setpoint_rad", "rad", "commanded servo angle")}
        self.outputs: Mapping[str, Port] = {
            "angle_rad": Port("angle_rad", "rad", f"servo angle ({self.estimate_source})"),
            "rate_rad_s": Port("rate_rad_s", "rad/s", "finite-difference angular rate"),
            "accel_rad_s2": Port("accel_rad_s2", "rad/s2", "finite-difference angular accel")}
        self._session, self._plan = _session_and_read_plan(
            self.map, self.map.position.spans() if self.map.position is not None else [])
        self._target_rad = self._command_rad = safe_rad
        self._angle_rad, self._rate_rad_s, self._accel_rad_s2 = safe_rad, 0.0, 0.0
        self._t_read: float | None = None
        self._enabled_generation: int | None = None
        self.status = Status()

    @property
    def command_rad(self) -> float:
        """The last setpoint sent (after clamping and rate limiting)."""
        return self._command_rad

    def clamp(self, setpoint_rad: float) -> float:
        return min(max(setpoint_rad, self.limits_rad[0]), self.limits_rad[1])

    def start(self, t0_s: float) -> None:
        self._open()
        self._started = True
        self._enabled_generation = None
        with self._patient_start():
            if self.map.position is not None:
                self._guard(t0_s, self._read)
                # Start from where the servo is, so the first step does not jump.
                self._command_rad = self._target_rad = self.clamp(self._angle_rad)
            self._rate_rad_s = self._accel_rad_s2 = 0.0
            self._guard(t0_s, self._write)

    def set_inputs(self, values: Mapping[str, float]) -> None:
        unknown = set(values) - {"setpoint_rad"}
        if unknown:
            raise HILError(f"{self.name}: unknown inputs {sorted(unknown)}; inputs: setpoint_rad")
        if "setpoint_rad" in values:
            x = float(values["setpoint_rad"])
            if not math.isfinite(x):
                raise HILError(f"{self.name}: setpoint_rad = {x} is not finite")
            self._target_rad = self.clamp(x)

    def get_outputs(self) -> dict[str, float]:
        self._check_started()
        return {"angle_rad": self._angle_rad, "rate_rad_s": self._rate_rad_s,
                "accel_rad_s2": self._accel_rad_s2}

    def do_step(self, t_s: float, h_s: float) -> None:
        self._check_started()
        previous = self._command_rad
        step_rad = self.rate_limit_rad_s * max(h_s, 0.0)
        self._command_rad = min(max(self._target_rad, previous - step_rad), previous + step_rad)
        self._guard(t_s + h_s, self._write)
        if self._plan.groups:
            self._guard(t_s + h_s, self._read)
            self._note_lag(t_s + h_s, self.status)
            self._note_restart(t_s + h_s)
        if self.map.position is None and h_s > 0:
            rate = (self._command_rad - previous) / h_s
            self._accel_rad_s2 = (rate - self._rate_rad_s) / h_s
            self._angle_rad, self._rate_rad_s = self._command_rad, rate

    def close(self) -> None:
        """Command the safe position, retrying until safe_timeout_s; never raises."""
        try:
            if self._link is not None:
                self._command_rad = self.safe_rad
                self.safe_confirmed = self._command_safe()
        except Exception as exc:   # close must not raise, whatever the bus does
            self.safe_confirmed = False
            log.warning("%s: could not command the safe position %g rad on close: %s",
                        self.name, self.safe_rad, exc)
        finally:
            self._started = False
            try:
                self._release()
            except Exception as exc:
                log.warning("%s: releasing the link failed: %s", self.name, exc)

    def _command_safe(self) -> bool:
        deadline = time.monotonic() + self.safe_timeout_s
        last = "no attempt"
        self.link.set_timeout(max(self.link.timeout_s, self.start_timeout_s))
        # A fresh connection: a stop signal may have cut a request short, and its late reply
        # must not be taken for the answer to the safe command.
        self.link.reset()
        while True:
            try:
                self._write()
                return True
            except FaultSignal as signal:
                last = f"{signal.fault.value}: {signal.detail}"
                self.link.reset()
            if time.monotonic() + _SAFE_RETRY_PAUSE_S >= deadline:
                break
            time.sleep(_SAFE_RETRY_PAUSE_S)
        log.error("%s: the safe position %g rad was NOT acknowledged within safe_timeout_s=%g s "
                  "(%s); check the servo by hand", self.name, self.safe_rad,
                  self.safe_timeout_s, last)
        return False

    def _write(self) -> None:
        # Enable on every new connection: the device behind it may have rebooted (and lost
        # its enable) while the link was down, possibly noticed by another block on the link.
        generation = self.link.connect()
        if generation != self._enabled_generation:
            if self.map.enable is not None:
                self.link.write_one(self.map.enable.address, self.map.enable.value, self.url.unit)
            if self.map.watchdog is not None:   # the device's own guard against a dead client
                self.link.write_one(self.map.watchdog.address, self.map.watchdog.timeout_ms,
                                    self.url.unit)
            self._enabled_generation = generation
        sp = self.map.setpoint
        self.link.write(sp.address, encode_value(sp, self._command_rad / sp.to_si), self.url.unit)

    def _read(self) -> None:
        regs = self._plan.read(self.link, self.url.unit)
        now = time.monotonic()
        if self.map.status is not None:
            self.status = decode_status(self.map.status, regs[self.map.status.address])
            if self.status.error:
                raise FaultSignal(Fault.DEVICE_ERROR, "servo controller error bit set")
        if self._session is not None and (restart := self._session.check(regs, now)):
            # A controller that restarted lost its enable (and watchdog): send them again.
            self._restart, self._enabled_generation = restart, None
        if self.map.position is None:
            return
        angle = field_value(self.map.position, regs) * self.map.position.to_si
        if self._t_read is not None and now - self._t_read > 1e-6:
            dt = now - self._t_read
            rate = (angle - self._angle_rad) / dt
            self._accel_rad_s2 = (rate - self._rate_rad_s) / dt
            self._rate_rad_s = rate
        self._angle_rad, self._t_read = angle, now
