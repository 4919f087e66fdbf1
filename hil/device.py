"""What the hardware blocks share: a link, fault policy, and batched reads.

Fault policy: any fault seen during an operation (link or data) either raises DeviceFault at
once, or, when `reconnect_s` is set, retries the whole operation (re-dialling the link as
needed) until it succeeds or `reconnect_s` has passed, then raises. A step that recovers is
late by the recovery time; the pacer records that as a deadline miss.
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence, TypeVar

from hil.errors import DeviceFault, Fault, HILConfigError, HILError
from hil.link import FaultSignal, Link, acquire_link, check_transport, parse_url, release_link
from hil.codec import decode_value
from hil.registers import Function, NumberField

log = logging.getLogger(__name__)
T = TypeVar("T")
_RETRY_PAUSE_S = 0.02   # between recovery attempts: quick, without hammering a rebooting device


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
                 reconnect_s: float | None) -> None:
        if not timeout_s > 0:
            raise HILConfigError(f"{name}: timeout_s must be positive, got {timeout_s}")
        if reconnect_s is not None and not reconnect_s > 0:
            raise HILConfigError(f"{name}: reconnect_s must be positive or None, "
                                 f"got {reconnect_s}")
        self.name = name
        self.url = parse_url(url)
        check_transport(self.url)
        self.timeout_s = timeout_s
        self.reconnect_s = reconnect_s
        self._link: Link | None = None
        self._started = False

    def _open(self) -> None:
        if self._link is None:
            self._link = acquire_link(self.url, self.timeout_s)

    @property
    def link(self) -> Link:
        if self._link is None:
            raise HILError(f"{self.name}: not started (call start() first)")
        return self._link

    def _guard(self, t_s: float, operation: Callable[[], T]) -> T:
        try:
            return operation()
        except FaultSignal as signal:
            last = signal
        if self.reconnect_s is None:
            raise DeviceFault(self.name, last.fault, t_s, last.detail)
        log.warning("%s: %s at t=%.4f s (%s); recovering for up to %g s", self.name,
                    last.fault.value, t_s, last.detail, self.reconnect_s)
        deadline = time.monotonic() + self.reconnect_s
        while (remaining := deadline - time.monotonic()) > 0:
            time.sleep(min(_RETRY_PAUSE_S, remaining))
            try:
                return operation()
            except FaultSignal as signal:
                last = signal
        raise DeviceFault(self.name, last.fault, t_s,
                          f"{last.detail}; not cleared within reconnect_s={self.reconnect_s} s")

    def _release(self) -> None:
        if self._link is not None:
            link, self._link = self._link, None
            release_link(link)

    def _check_started(self) -> None:
        if not self._started:
            raise HILError(f"{self.name}: not started (call start() first)")
