"""Errors of the hardware-in-the-loop package.

HILError                 (featherstar.fmu_src.errors.FeatherstarError)
├── HILConfigError       a register map or device URL is malformed; raised before any I/O
└── DeviceFault          a device misbehaved at run time: timeout, lost link, exception
                         response, stale or out-of-range data. Carries what the recorder's
                         fault note needs (device, fault, run time, wall time).
"""
from __future__ import annotations

import datetime as _dt
import enum

from ..fmu_src.errors import FeatherstarError


class HILError(FeatherstarError):
    """Root of the errors raised by `hil`."""


class HILConfigError(HILError):
    """A register map file or a device URL is malformed."""


class Fault(str, enum.Enum):
    """What went wrong with a device. The values are what `fault.json` records."""

    CONNECT = "connect"                        # the link could not be opened
    TIMEOUT = "timeout"                        # no (complete) reply within timeout_s
    LINK_LOST = "link_lost"                    # socket or serial line closed under us
    EXCEPTION_RESPONSE = "exception_response"  # the device answered with a Modbus exception
    STALE = "stale"                            # value frozen, or never stable, for too long
    OUT_OF_RANGE = "out_of_range"              # beyond the map's range, NaN, bad decimals
    OVERLOAD = "overload"                      # the device's overload bit is set
    DEVICE_ERROR = "device_error"              # the device's error bit is set


class DeviceFault(HILError):
    """A run-time hardware fault: names the device, the fault, the run time and the wall time."""

    def __init__(self, device: str, fault: Fault, t_s: float, detail: str,
                 wall_time: str | None = None) -> None:
        self.device = device
        self.fault = Fault(fault)
        self.t_s = t_s
        self.detail = detail
        self.wall_time = wall_time or _dt.datetime.now(_dt.timezone.utc).isoformat(
            timespec="milliseconds")
        super().__init__(
            f"{device}: {self.fault.value} at t={t_s:.4f} s (wall {self.wall_time}): {detail}")

    def __reduce__(self):
        # Survives pickling (a run in a worker process) with its fields, not just the message.
        return (DeviceFault, (self.device, self.fault, self.t_s, self.detail, self.wall_time))

    def to_dict(self) -> dict[str, object]:
        return {"device": self.device, "fault": self.fault.value, "t_s": self.t_s,
                "wall_time": self.wall_time, "detail": self.detail}
