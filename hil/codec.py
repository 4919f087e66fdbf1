"""Register encoding shared by the client blocks and the emulator, so every map option means
the same on both sides: 32-bit numbers in four word orders (pymodbus has only ABCD and CDAB),
int32 with decimals, scale and offset, and status bits."""
from __future__ import annotations

import struct
from typing import Sequence

from .registers import (MAX_DECIMALS, NumberField, Status, StatusField, ValueType,
                           WordOrder)

# Byte permutations from big-endian ABCD. Each is its own inverse, so one table both encodes
# and decodes.
_PERMUTATION = {WordOrder.ABCD: (0, 1, 2, 3), WordOrder.CDAB: (2, 3, 0, 1),
                WordOrder.BADC: (1, 0, 3, 2), WordOrder.DCBA: (3, 2, 1, 0)}
_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1
_FLOAT32_MAX = 3.4028234663852886e38


def words_from_bytes(data: bytes, order: WordOrder) -> list[int]:
    """Four big-endian bytes ABCD -> two registers in `order`."""
    b = bytes(data[i] for i in _PERMUTATION[order])
    return [(b[0] << 8) | b[1], (b[2] << 8) | b[3]]


def bytes_from_words(registers: Sequence[int], order: WordOrder) -> bytes:
    """Two registers in `order` -> four big-endian bytes ABCD."""
    if len(registers) != 2:
        raise ValueError(f"a 32-bit value needs 2 registers, got {len(registers)}")
    raw = struct.pack(">HH", *registers)
    return bytes(raw[i] for i in _PERMUTATION[order])


def encode_raw(raw: int | float, value_type: ValueType, order: WordOrder) -> list[int]:
    if value_type is ValueType.FLOAT32:
        return words_from_bytes(struct.pack(">f", raw), order)
    return words_from_bytes(struct.pack(">i", raw), order)


def decode_raw(registers: Sequence[int], value_type: ValueType, order: WordOrder) -> int | float:
    fmt = ">f" if value_type is ValueType.FLOAT32 else ">i"
    return struct.unpack(fmt, bytes_from_words(registers, order))[0]


def _decimals(field: NumberField, decimals: int | None) -> int:
    if field.type is ValueType.FLOAT32:
        return 0
    if field.decimals is not None:
        return field.decimals
    if decimals is None:
        raise ValueError("this field reads its decimals from a register: pass decimals=")
    if not 0 <= decimals <= MAX_DECIMALS:
        raise ValueError(f"decimals register reads {decimals}, outside 0..{MAX_DECIMALS}")
    return decimals


def encode_value(field: NumberField, x: float, decimals: int | None = None) -> list[int]:
    """Engineering value -> registers. Saturates at the number type's limits, as devices do."""
    raw = (x - field.offset) / field.scale
    if field.type is ValueType.FLOAT32:
        return encode_raw(max(-_FLOAT32_MAX, min(_FLOAT32_MAX, raw)), field.type,
                          field.word_order)
    counts = round(raw * 10 ** _decimals(field, decimals))
    return encode_raw(max(_INT32_MIN, min(_INT32_MAX, counts)), field.type, field.word_order)


def decode_value(field: NumberField, registers: Sequence[int],
                 decimals: int | None = None) -> float:
    """Registers -> engineering value (in `field.unit`; multiply by `field.to_si` for SI)."""
    raw = decode_raw(registers, field.type, field.word_order)
    return raw / 10 ** _decimals(field, decimals) * field.scale + field.offset


def encode_status(field: StatusField, status: Status) -> int:
    word = 0
    for bit, on in ((field.stable_bit, status.stable), (field.overload_bit, status.overload),
                    (field.error_bit, status.error), (field.lag_bit, status.lagging)):
        if bit is not None and on:
            word |= 1 << bit
    return word


def decode_status(field: StatusField, word: int) -> Status:
    """Bits the map does not define read as the harmless state (stable, no overload/error/lag)."""
    def bit(n: int | None, default: bool) -> bool:
        return default if n is None else bool(word >> n & 1)
    return Status(stable=bit(field.stable_bit, True), overload=bit(field.overload_bit, False),
                  error=bit(field.error_bit, False), lagging=bit(field.lag_bit, False))
