"""Typed FMU variable access for featherstar.cosim.fmi.fmu_block: fmi3Get/Set<Type> (every FMI 3.0 type, arrays,
Binary) and fmi2Get/Set<Real|Integer|Boolean|String>, through raw ctypes prototypes, with the
conversions between an FMU's own types and the master's float64 port buffers (featherstar.cosim.fmi.fmi_types).

Scalar Float64 ports do not come here: fmu_block keeps its allocation-free fast path for them.
"""
from __future__ import annotations

import ctypes
from ctypes import (
    CFUNCTYPE,
    c_bool,
    c_char_p,
    c_double,
    c_float,
    c_int,
    c_int8,
    c_int16,
    c_int32,
    c_int64,
    c_size_t,
    c_uint,
    c_uint8,
    c_uint16,
    c_uint32,
    c_uint64,
    c_void_p,
)
from dataclasses import dataclass
from typing import Any, Callable

from .fmi_types import CARRIER_EXACT, INT_RANGES, intern, interned

_C3 = {"Float64": c_double, "Float32": c_float, "Int8": c_int8, "UInt8": c_uint8, "Int16": c_int16,
       "UInt16": c_uint16, "Int32": c_int32, "UInt32": c_uint32, "Int64": c_int64, "UInt64": c_uint64,
       "Boolean": c_bool, "String": c_char_p, "Binary": c_void_p}
_FMI2 = {"Float64": ("Real", c_double), "Int32": ("Integer", c_int), "Boolean": ("Boolean", c_int),
         "String": ("String", c_char_p)}


@dataclass(frozen=True)
class PortVar:
    """Where a port lives in the FMU: the variable's value reference and type; for an element of
    an FMI 3.0 array, its flat (row-major) index and the array's size."""

    vr: int
    type: str
    element: int = 0
    size: int = 1
    discrete: bool = False

    @property
    def fast(self) -> bool:
        """A scalar Float64: handled by fmu_block's preallocated fast path."""
        return self.type == "Float64" and self.size == 1


class CarrierError(Exception):
    """A value the float64 carrier cannot hold exactly."""


def to_carrier(type_: str, value: Any) -> float:
    if type_ in ("String", "Binary"):
        return intern(value)
    if type_ == "Boolean":
        return 1.0 if value else 0.0
    if type_ in INT_RANGES and abs(int(value)) > CARRIER_EXACT:
        raise CarrierError(f"{type_} value {int(value)} is beyond 2**53 and cannot be passed on exactly")
    return float(value)


def from_carrier(type_: str, code: float) -> Any:
    if type_ in ("String", "Binary"):
        return interned(code)
    if type_ == "Boolean":
        return code != 0.0
    if type_ in INT_RANGES:
        return int(code)
    return code


class TypedAccess:
    """Get/Set of any supported type on one instance; values as Python lists."""

    def __init__(self, dll: Any, instance: Any, fmi3: bool) -> None:
        self.dll, self.inst, self.fmi3 = dll, instance, fmi3
        self._fns: dict[tuple[str, str], Callable[..., int]] = {}

    def _fn(self, op: str, type_: str) -> Callable[..., int]:
        key = (op, type_)
        fn = self._fns.get(key)
        if fn is None:
            if self.fmi3:
                name = f"fmi3{op}{type_}"
                args = [c_void_p, c_void_p, c_size_t, c_void_p, c_void_p, c_size_t] if type_ == "Binary" else \
                    [c_void_p, c_void_p, c_size_t, c_void_p, c_size_t]
            else:
                name = f"fmi2{op}{_FMI2[type_][0]}"
                args = [c_void_p, c_void_p, c_size_t, c_void_p]
            address = ctypes.cast(getattr(self.dll, name), c_void_p).value
            fn = CFUNCTYPE(c_int, *args)(address)
            fn.fmi_name = name  # type: ignore[attr-defined]
            self._fns[key] = fn
        return fn

    def name(self, op: str, type_: str) -> str:
        return f"fmi3{op}{type_}" if self.fmi3 else f"fmi2{op}{_FMI2[type_][0]}"

    def _ctype(self, type_: str) -> Any:
        return _C3[type_] if self.fmi3 else _FMI2[type_][1]

    def set(self, type_: str, vrs: list[int], values: list[Any]) -> int:
        vr = (c_uint * len(vrs))(*vrs)
        ctype = self._ctype(type_)
        fn = self._fn("Set", type_)
        if type_ == "String":
            data = (c_char_p * len(values))(*[str(v).encode("utf-8") for v in values])
        elif type_ == "Binary":
            blobs = [ctypes.create_string_buffer(bytes(v), max(len(v), 1)) for v in values]
            sizes = (c_size_t * len(values))(*[len(v) for v in values])
            data = (c_void_p * len(values))(*[ctypes.addressof(b) for b in blobs])
            return fn(self.inst, ctypes.addressof(vr), len(vrs), ctypes.addressof(sizes),
                      ctypes.addressof(data), len(values))
        else:
            data = (ctype * len(values))(*values)
        if self.fmi3:
            return fn(self.inst, ctypes.addressof(vr), len(vrs), ctypes.addressof(data), len(values))
        return fn(self.inst, ctypes.addressof(vr), len(vrs), ctypes.addressof(data))

    def get(self, type_: str, vrs: list[int], n_values: int) -> tuple[int, list[Any]]:
        vr = (c_uint * len(vrs))(*vrs)
        ctype = self._ctype(type_)
        fn = self._fn("Get", type_)
        data = (ctype * n_values)()
        if type_ == "Binary":
            sizes = (c_size_t * n_values)()
            status = fn(self.inst, ctypes.addressof(vr), len(vrs), ctypes.addressof(sizes),
                        ctypes.addressof(data), n_values)
            if status > 1:
                return status, []
            return status, [ctypes.string_at(data[i], sizes[i]) if data[i] else b"" for i in range(n_values)]
        if self.fmi3:
            status = fn(self.inst, ctypes.addressof(vr), len(vrs), ctypes.addressof(data), n_values)
        else:
            status = fn(self.inst, ctypes.addressof(vr), len(vrs), ctypes.addressof(data))
        if status > 1:
            return status, []
        if type_ == "String":
            return status, [(v or b"").decode("utf-8", "replace") for v in data]
        return status, list(data)


class TypedPorts:
    """Setters and getters (closures for the master's schedules) of an FMU unit's ports that are
    not scalar Float64: one call per type for scalars, one per array variable (an array input
    is set whole: its unconnected elements keep the values read from the FMU)."""

    def __init__(self, access: TypedAccess, inputs: list[PortVar], outputs: list[PortVar], output_names: list[str],
                 inbuf: Any, outbuf: Any, *, fail: Callable[[str, int], Exception],
                 carry_error: Callable[[str, str], Exception]) -> None:
        self.access, self.inputs, self.outputs, self.output_names = access, inputs, outputs, output_names
        self.inbuf, self.outbuf = inbuf, outbuf
        self.fail, self.carry_error = fail, carry_error
        self._arrays: dict[int, list[Any]] = {}

    @staticmethod
    def _calls(ports: list[PortVar], idx: Any) -> list[tuple[str, list[int], list[int]]]:
        """(type, value references, port indices) per FMI call."""
        scalars: dict[str, list[int]] = {}
        arrays: dict[int, list[int]] = {}
        for i in idx:
            pv = ports[i]
            (arrays.setdefault(pv.vr, []) if pv.size > 1 else scalars.setdefault(pv.type, [])).append(i)
        return ([(t, [ports[i].vr for i in items], items) for t, items in scalars.items()] +
                [(ports[items[0]].type, [vr], items) for vr, items in arrays.items()])

    def _array(self, pv: PortVar) -> list[Any]:
        values = self._arrays.get(pv.vr)
        if values is None:
            status, values = self.access.get(pv.type, [pv.vr], pv.size)
            if status > 1:
                raise self.fail(self.access.name("Get", pv.type), status)
            self._arrays[pv.vr] = values
        return values

    def setter(self, idx: Any) -> Callable[[], None]:
        calls, access, inbuf, ports = self._calls(self.inputs, idx), self.access, self.inbuf, self.inputs

        def push() -> None:
            for type_, vrs, items in calls:
                if ports[items[0]].size > 1:
                    values = self._array(ports[items[0]])
                    for i in items:
                        values[ports[i].element] = from_carrier(type_, inbuf[i])
                else:
                    values = [from_carrier(type_, inbuf[i]) for i in items]
                status = access.set(type_, vrs, values)
                if status > 1:
                    raise self.fail(f"{access.name('Set', type_)} (inputs)", status)
        return push

    def getter(self, idx: Any) -> Callable[[], None]:
        calls, access, outbuf, ports = self._calls(self.outputs, idx), self.access, self.outbuf, self.outputs

        def get() -> None:
            for type_, vrs, items in calls:
                size = ports[items[0]].size
                status, values = access.get(type_, vrs, len(vrs) * size)
                if status > 1:
                    raise self.fail(f"{access.name('Get', type_)} (outputs)", status)
                for j, i in enumerate(items):
                    try:
                        outbuf[i] = to_carrier(type_, values[ports[i].element if size > 1 else j])
                    except CarrierError as exc:
                        raise self.carry_error(f"output {self.output_names[i]}: {exc}",
                                               access.name("Get", type_)) from None
        return get
