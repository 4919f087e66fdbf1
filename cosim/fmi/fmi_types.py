"""FMI variable types in scenes: port types, which connections convert safely, and how values of
each type travel through the master's float64 port buffers.

Port types are the FMI 3.0 names (FMI 2.0 Real is Float64, Integer and Enumeration are Int32;
FMI 3.0 Enumeration is Int64). Every port value travels as one float64 in the units' `inbuf` /
`outbuf`, so the schedules, loops, recording and dedup of the master need no type cases:

* Float64, Float32, Boolean (0/1) and integers up to 32 bits are exact in a float64;
* Int64 and UInt64 are exact up to 2**53: a larger value read from an FMU stops the run with a
  StepError naming the port (it is never rounded silently);
* String and Binary values are interned: the buffer holds the value's index in a process-wide
  table (`intern` / `interned`), so a string output drives a string input through the same
  copy as a float, and `typed_signal` turns a recorded column back into strings or bytes.

A connection is allowed when every value of the source type is exactly a value of the input's
type (`conversion_problem`): Int8 -> Int16, UInt16 -> Int32, any integer of <= 32 bits or
Boolean -> Float64, Float32 -> Float64, ... Anything that could round, wrap, truncate or change
meaning is refused with the reason (Float64 -> Float32, Float -> Int, Int64 -> Float64,
signed -> unsigned, number -> Boolean, String/Binary <-> anything else).
"""
from __future__ import annotations

from typing import Any

import numpy as np

FLOAT64 = "Float64"
OBJECT_TYPES = ("String", "Binary")
INT_RANGES: dict[str, tuple[int, int]] = {
    "Boolean": (0, 1),
    "Int8": (-(2 ** 7), 2 ** 7 - 1), "UInt8": (0, 2 ** 8 - 1),
    "Int16": (-(2 ** 15), 2 ** 15 - 1), "UInt16": (0, 2 ** 16 - 1),
    "Int32": (-(2 ** 31), 2 ** 31 - 1), "UInt32": (0, 2 ** 32 - 1),
    "Int64": (-(2 ** 63), 2 ** 63 - 1), "UInt64": (0, 2 ** 64 - 1),
}
#: integers a float type holds exactly: |n| <= 2**mantissa bits
FLOAT_EXACT = {"Float64": 2 ** 53, "Float32": 2 ** 24}
TYPES = ("Float64", "Float32", *INT_RANGES, *OBJECT_TYPES)
#: largest integer magnitude the float64 carrier holds exactly
CARRIER_EXACT = FLOAT_EXACT["Float64"]

_FMI2 = {"Real": "Float64", "Integer": "Int32", "Enumeration": "Int32", "Boolean": "Boolean", "String": "String"}
NUMPY_DTYPE = {"Float64": np.float64, "Float32": np.float32, "Boolean": np.bool_, "Int8": np.int8,
               "UInt8": np.uint8, "Int16": np.int16, "UInt16": np.uint16, "Int32": np.int32,
               "UInt32": np.uint32, "Int64": np.int64, "UInt64": np.uint64}


def port_type(fmi_type: str, fmi3: bool) -> str | None:
    """The port type of an FMI variable type name; None if it cannot be a port (Clock)."""
    if fmi3:
        if fmi_type == "Enumeration":
            return "Int64"
        return fmi_type if fmi_type in TYPES else None
    return _FMI2.get(fmi_type)


def conversion_problem(src: str, dst: str) -> str | None:
    """Why an output of type src may not drive an input of type dst (None: it may, exactly)."""
    if src == dst:
        return None
    if src in OBJECT_TYPES or dst in OBJECT_TYPES:
        return f"{src} cannot drive {dst}: only {src} inputs take {src} values" if src in OBJECT_TYPES else \
            f"{src} cannot drive {dst}: only {dst} outputs give {dst} values"
    if src in FLOAT_EXACT:
        if dst in FLOAT_EXACT:
            return None if FLOAT_EXACT[src] <= FLOAT_EXACT[dst] else (
                f"{src} -> {dst} would round (put a block that converts explicitly in between)")
        return f"{src} -> {dst} would truncate or round a real number to an integer (no implicit rounding)"
    lo, hi = INT_RANGES[src]
    if dst in FLOAT_EXACT:
        if max(-lo, hi) <= FLOAT_EXACT[dst]:
            return None
        return f"{src} -> {dst} would round integers beyond 2**{FLOAT_EXACT[dst].bit_length() - 1}"
    if dst == "Boolean":
        return f"{src} -> Boolean would change meaning (compare explicitly instead)"
    dlo, dhi = INT_RANGES[dst]
    if dlo <= lo and hi <= dhi:
        return None
    return f"{src} -> {dst} would overflow or wrap ({src} spans {lo}..{hi}, {dst} {dlo}..{dhi})"


# --- String and Binary values in float64 buffers -------------------------------------------------

_VALUES: list[Any] = []
_INDEX: dict[tuple[type, Any], int] = {}


def intern(value: str | bytes) -> float:
    """The float64 that stands for a String or Binary value (the same value, the same float)."""
    key = (type(value), value)
    index = _INDEX.get(key)
    if index is None:
        index = len(_VALUES)
        _VALUES.append(value)
        _INDEX[key] = index
    return float(index)


def interned(code: float) -> Any:
    """The String or Binary value a float from `intern` stands for."""
    return _VALUES[int(code)]


def typed_signal(port_type_: str, column: np.ndarray) -> np.ndarray:
    """A recorded float64 column as the port's own type (strings and bytes as object arrays)."""
    if port_type_ in OBJECT_TYPES:
        out = np.empty(len(column), dtype=object)
        for i, code in enumerate(column):
            out[i] = interned(code) if np.isfinite(code) else None
        return out
    dtype = NUMPY_DTYPE.get(port_type_)
    if dtype is None or dtype is np.float64 or not np.all(np.isfinite(column)):
        return column
    return column.astype(dtype)


def parameter_value(port_type_: str, value: Any, where: str) -> Any:
    """A scene parameter value converted to the FMU variable's type, or a one-line ValueError."""
    if port_type_ == "String":
        if isinstance(value, str):
            return value
        if isinstance(value, bool):  # --set KEY=true arrives parsed
            return "true" if value else "false"
        if isinstance(value, (int, float)):  # --set KEY=42 arrives parsed
            return str(value)
        raise ValueError(f"{where}: {value!r} is not a string")
    if port_type_ == "Binary":
        if isinstance(value, (bytes, bytearray)):
            return bytes(value)
        try:
            return bytes.fromhex(str(value))
        except ValueError:
            raise ValueError(f"{where}: {value!r} is not hexadecimal bytes (e.g. \"00ff\")") from None
    if port_type_ == "Boolean":
        if isinstance(value, bool):
            return value
        if isinstance(value, (int, float)) and value in (0, 1):
            return bool(value)
        if isinstance(value, str) and value.lower() in ("true", "false"):
            return value.lower() == "true"
        raise ValueError(f"{where}: {value!r} is not a Boolean (true or false)")
    if isinstance(value, bool) or isinstance(value, str):
        raise ValueError(f"{where}: {value!r} is not a number")
    if port_type_ in INT_RANGES:
        if isinstance(value, float):
            if not value.is_integer():
                raise ValueError(f"{where}: {value!r} is not an integer ({port_type_})")
            value = int(value)
        lo, hi = INT_RANGES[port_type_]
        if not lo <= int(value) <= hi:
            raise ValueError(f"{where}: {value} is outside {port_type_} ({lo}..{hi})")
        return int(value)
    return float(value)
