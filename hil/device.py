"""What the hardware blocks share: a link, fault policy, and batched reads.

Fault policy: any fault seen during an operation (link or data) either raises DeviceFault at
once, or, when `reconnect_s` is set, retries the whole operation (re-dialling the link as
needed) until it succeeds or `reconnect_s` has passed, then raises. A step that recovers is
late by the recovery time; the pacer records that as a deadline miss.

Start-up is patient whatever `reconnect_s` says: connecting, taring and enabling use
`start_timeout_s` per request (a real transmitter can take hundreds of milliseconds to answer
its first request) and are retried for up to `start_retry_s`; the per-step `timeout_s` applies
once the run is under way.

Every recovery, every new connection seen after start, and every report of an emulated
device that its plant fell behind real time (the status lag bit) is appended to `events` (dicts with
t_s, kind, device, detail): the master uses them to exclude the periods they touch from the
metrics (featherstar.cosim.swimmer.validity), so a recovered fault is never silent.
"""
from __future__ import annotations

import logging
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable, Iterator, Mapping, Sequence, TypeVar

from ..cosim.coupling.pacing import STOP
from .codec import decode_value
from .errors import DeviceFault, Fault, HILConfigError, HILError
from .link import FaultSignal, Link, acquire_link, check_transport, parse_url, release_link
from .registers import Function, NumberField, Status

log = logging.getLogger(__name__)
T = TypeVar("T")
_RETRY_PAUSE_S = 0.02   # between recovery attempts: quick, without hammering a rebooting device
# What a slow or still-booting device looks like at start; worth retrying for start_retry_s.
_SLOW_START_FAULTS = (Fault.CONNECT, Fault.TIMEOUT, Fault.LINK_LOST)


@dataclass(frozen=True)
class ReadPlan:
    """Registers to read each sample, grouped so that contiguous ones take one request."""

    function: Function
    groups: tuple[tuple[int, int], ...]    # (address, count)

    @staticmethod
    def build(function: Function, spans: Sequence[tuple[int, int]]) -> ReadPlan:
        groups: list[list[int]] = []
        for address, count in sorted(spans):
            if groups and address <= groups[-1][0] + groups[-1][1]:
                groups[-1][1] = max(groups[-1][1], address + count - groups[-1][0])
            else:
                groups.append([address, count])
        return ReadPlan(function, tuple((a, n) for a, n in groups))

    def read(self, link: Link, unit: int) -> dict[int, int]:
        """Address -> register value for every planned address."""
        values: dict[int, int] = {}
        for address, count in self.groups:
            values.update(zip(range(address, address + count),
                              link.read(self.function, address, count, unit)))
        return values


def field_value(field: NumberField, regs: Mapping[int, int]) -> float:
    """Decode a number field from a ReadPlan result, in the field's engineering unit; raises
    FaultSignal for a bad decimals register or a reading outside the map's range."""
    decimals = None if field.decimals_address is None else regs[field.decimals_address]
    try:
        value = decode_value(field, [regs[field.address], regs[field.address + 1]], decimals)
    except ValueError as exc:
        raise FaultSignal(Fault.OUT_OF_RANGE, str(exc)) from None
    if not math.isfinite(value) or (field.min is not None and value < field.min) \
            or (field.max is not None and value > field.max):
        raise FaultSignal(Fault.OUT_OF_RANGE, f"reads {value:g} {field.unit}, outside the map's "
                                              f"range [{field.min}, {field.max}]")
    return value


class ModbusDevice:
    """Base of the hardware blocks: owns the link and applies the fault policy."""

    def __init__(self, name: str, url: str, *, timeout_s: float,
                 reconnect_s: float | None, start_timeout_s: float = 1.0,
                 start_retry_s: float = 5.0) -> None:
        for label, value in (("timeout_s", timeout_s), ("start_timeout_s", start_timeout_s),
                             ("start_retry_s", start_retry_s)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise HILConfigError(f"{name}: {label} must be positive (seconds), "
                                     f"got {value!r}")
        if reconnect_s is not None and not (isinstance(reconnect_s, (int, float))
                                            and math.isfinite(reconnect_s) and reconnect_s > 0):
            raise HILConfigError(f"{name}: reconnect_s must be positive or None, "
                                 f"got {reconnect_s!r}")
        self.name = name
        self.url = parse_url(url)
        check_transport(self.url)
        self.timeout_s = float(timeout_s)
        self.reconnect_s = reconnect_s
        self.start_timeout_s = float(start_timeout_s)
        self.start_retry_s = float(start_retry_s)
        self.events: list[dict[str, object]] = []
        self._link: Link | None = None
        self._started = False
        self._starting = False
        self._generation: int | None = None
        self._restart: str | None = None   # a device restart seen by the last read

    def _open(self) -> None:
        if self._link is None:
            self._link = acquire_link(self.url, self.timeout_s)

    @contextmanager
    def _patient_start(self) -> Iterator[None]:
        """Start-up timeouts and retries; the shared link's step timeout is restored after."""
        link = self.link
        step_timeout_s = link.timeout_s
        link.set_timeout(max(step_timeout_s, self.start_timeout_s))
        self._starting = True
        try:
            yield
        finally:
            self._starting = False
            link.set_timeout(step_timeout_s)
            self._generation = link.generation

    def _note(self, t_s: float, kind: str, detail: str, **extra: object) -> None:
        self.events.append({"t_s": t_s, "kind": kind, "device": self.name, "detail": detail,
                            **extra})

    def _note_lag(self, t_s: float, status: Status) -> None:
        """An emulated device whose plant fell behind real time (its status lag bit): the data
        around t_s lag the clock, so the master excludes the period (featherstar.cosim.swimmer.validity)."""
        if status.lagging:
            self._note(t_s, "lag", "the device reports its plant behind real time (lag bit)")

    def _note_restart(self, t_s: float, **extra: object) -> None:
        """A restart the [session] registers showed (featherstar.hil.session), as an event."""
        if self._restart is not None:
            self._note(t_s, "restart", self._restart, **extra)
            self._restart = None

    def _on_reconnect(self, t_s: float) -> None:
        """A new connection after start: the device may have rebooted. Blocks add what that
        means for their data (the load cell: the tare is unknown)."""
        self._note(t_s, "reconnect", f"new connection to {self.link.where}")

    @property
    def link(self) -> Link:
        if self._link is None:
            raise HILError(f"{self.name}: not started (call start() first)")
        return self._link

    def _guard(self, t_s: float, operation: Callable[[], T]) -> T:
        try:
            result = operation()
            self._check_generation(t_s)
            return result
        except FaultSignal as signal:
            last = signal
        budget_s, label = ((self.start_retry_s, "start_retry_s") if self._starting
                           else (self.reconnect_s, "reconnect_s"))
        if self._starting and last.fault not in _SLOW_START_FAULTS:
            budget_s = None   # an overload or a bad value at start is not slowness: stop now
        if budget_s is None:
            raise DeviceFault(self.name, last.fault, t_s, last.detail)
        log.warning("%s: %s at t=%.4f s (%s); recovering for up to %g s", self.name,
                    last.fault.value, t_s, last.detail, budget_s)
        t_fault = time.monotonic()
        deadline = t_fault + budget_s
        while (remaining := deadline - time.monotonic()) > 0:
            # A stop signal is honoured here, not after the whole budget: no command is pending.
            STOP.raise_if_requested()
            time.sleep(min(_RETRY_PAUSE_S, remaining))
            try:
                result = operation()
            except FaultSignal as signal:
                last = signal
                continue
            if not self._starting:
                gap_s = time.monotonic() - t_fault
                self._note(t_s, "gap", f"{last.fault.value}: {last.detail}; recovered after "
                                       f"{gap_s:.3f} s", duration_s=gap_s)
            self._check_generation(t_s)
            return result
        raise DeviceFault(self.name, last.fault, t_s,
                          f"{last.detail}; not cleared within {label}={budget_s} s")

    def _check_generation(self, t_s: float) -> None:
        if self._starting or self._link is None:
            return
        generation = self._link.generation
        if self._generation is not None and generation != self._generation:
            self._on_reconnect(t_s)
        self._generation = generation

    def _release(self) -> None:
        if self._link is not None:
            link, self._link = self._link, None
            release_link(link)

    def _check_started(self) -> None:
        if not self._started:
            raise HILError(f"{self.name}: not started (call start() first)")
