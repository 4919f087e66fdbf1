"""Register maps and codec: encode/decode round trips for every option, clear errors for bad
maps."""
from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, strategies as st
from pymodbus.client import ModbusTcpClient

from featherstar.hil.errors import HILConfigError
from featherstar.hil.codec import (decode_raw, decode_status, decode_value, encode_raw, encode_status,
                       encode_value)
from featherstar.hil.registers import (NumberField, Status, StatusField, ValueType, WordOrder,
                           available_maps, load_loadcell_map, load_map, load_servo_map)

ORDERS = list(WordOrder)


def field(value_type: ValueType, order: WordOrder, **kw) -> NumberField:
    return NumberField(address=0, type=value_type, word_order=order, unit="kg", to_si=9.80665,
                       **kw)


@pytest.mark.parametrize("order, expected", [
    (WordOrder.ABCD, [0x3F80, 0x0000]), (WordOrder.CDAB, [0x0000, 0x3F80]),
    (WordOrder.BADC, [0x803F, 0x0000]), (WordOrder.DCBA, [0x0000, 0x803F])])
def test_float32_word_orders_match_known_vectors(order, expected):
    assert encode_raw(1.0, ValueType.FLOAT32, order) == expected
    assert decode_raw(expected, ValueType.FLOAT32, order) == 1.0


@pytest.mark.parametrize("order, expected", [
    (WordOrder.ABCD, [0x1234, 0x5678]), (WordOrder.CDAB, [0x5678, 0x1234]),
    (WordOrder.BADC, [0x3412, 0x7856]), (WordOrder.DCBA, [0x7856, 0x3412])])
def test_int32_word_orders_match_known_vectors(order, expected):
    assert encode_raw(0x12345678, ValueType.INT32, order) == expected
    assert decode_raw(expected, ValueType.INT32, order) == 0x12345678


@pytest.mark.parametrize("order, pymodbus_order", [(WordOrder.ABCD, "big"),
                                                    (WordOrder.CDAB, "little")])
@pytest.mark.parametrize("value_type, datatype, x", [
    (ValueType.FLOAT32, ModbusTcpClient.DATATYPE.FLOAT32, -1.25),
    (ValueType.INT32, ModbusTcpClient.DATATYPE.INT32, -123456)])
def test_agrees_with_pymodbus_where_pymodbus_has_the_order(order, pymodbus_order, value_type,
                                                           datatype, x):
    ours = encode_raw(x, value_type, order)
    assert ours == ModbusTcpClient.convert_to_registers(x, datatype, word_order=pymodbus_order)
    assert ModbusTcpClient.convert_from_registers(ours, datatype, word_order=pymodbus_order) == x


@pytest.mark.parametrize("order", ORDERS)
@given(x=st.floats(-1e6, 1e6), scale=st.sampled_from([1.0, -1.0, 0.001, 2.5]),
       offset=st.sampled_from([0.0, -0.5, 12.0]))
def test_float32_value_round_trips(order, x, scale, offset):
    f = field(ValueType.FLOAT32, order, scale=scale, offset=offset)
    y = decode_value(f, encode_value(f, x))
    assert y == pytest.approx(x, rel=1e-6, abs=1e-6 * (abs(offset) + abs(scale)))


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("fixed", [True, False])
@given(x=st.floats(-2000.0, 2000.0), decimals=st.integers(0, 5),
       scale=st.sampled_from([1.0, -1.0, 0.5]), offset=st.sampled_from([0.0, 0.25]))
def test_int32_value_round_trips_to_the_last_decimal(order, fixed, x, decimals, scale, offset):
    if fixed:
        f = field(ValueType.INT32, order, scale=scale, offset=offset, decimals=decimals)
        y = decode_value(f, encode_value(f, x))
    else:
        f = field(ValueType.INT32, order, scale=scale, offset=offset, decimals_address=5)
        y = decode_value(f, encode_value(f, x, decimals), decimals)
    assert abs(y - x) <= 0.5 * 10.0**-decimals * abs(scale) + 1e-9


def test_int32_saturates_instead_of_wrapping():
    f = field(ValueType.INT32, WordOrder.ABCD, decimals=3)
    assert decode_value(f, encode_value(f, 1e9)) == pytest.approx((2**31 - 1) / 1000)
    assert decode_value(f, encode_value(f, -1e9)) == pytest.approx(-(2**31) / 1000)


def test_decimals_register_outside_range_is_rejected():
    f = field(ValueType.INT32, WordOrder.ABCD, decimals_address=4)
    with pytest.raises(ValueError, match="decimals register reads 42"):
        decode_value(f, [0, 1], 42)


@given(stable=st.booleans(), overload=st.booleans(), error=st.booleans())
def test_status_bits_round_trip(stable, overload, error):
    f = StatusField(address=0, stable_bit=0, overload_bit=3, error_bit=15)
    s = Status(stable, overload, error)
    assert decode_status(f, encode_status(f, s)) == s


def test_undefined_status_bits_read_as_harmless():
    assert decode_status(StatusField(address=0), 0xFFFF) == Status(True, False, False)


def test_shipped_maps_load_with_their_documented_layout():
    assert set(available_maps()) >= {"loadcell-float32-abcd", "loadcell-int32-cdab",
                                     "servo-default"}
    f32 = load_loadcell_map("loadcell-float32-abcd")
    assert (f32.read_function.value, f32.value.type, f32.value.word_order) == \
        ("input", ValueType.FLOAT32, WordOrder.ABCD)
    i32 = load_loadcell_map("loadcell-int32-cdab")
    # 1-based in the file: value at 1, decimals at 3 -> protocol addresses 0 and 2.
    assert (i32.value.address, i32.value.decimals_address, i32.value.scale) == (0, 2, -1.0)
    servo = load_servo_map("servo-default")
    assert servo.position is not None and servo.enable is not None
    assert servo.setpoint.to_si == pytest.approx(math.pi / 180)


def test_map_of_the_wrong_kind_is_refused():
    with pytest.raises(HILConfigError, match="servo-default.toml.*kind = 'servo'"):
        load_loadcell_map("servo-default")
    with pytest.raises(HILConfigError, match="kind = 'loadcell'"):
        load_servo_map("loadcell-int32-cdab")


GOOD = """
[device]
kind = "loadcell"
function = "input"
address_base = 0
[value]
address = 0
type = "float32"
unit = "kg"
[status]
address = 2
stable_bit = 0
[tare]
address = 10
value = 1
"""


@pytest.mark.parametrize("old, new, expected", [
    ('type = "float32"', 'type = "float64"', r"\[value\] type = 'float64'.*valid values: "
                                             r"float32, int32"),
    ('function = "input"', 'function = "coil"', r"\[device\] function.*valid values: holding, "
                                                "input"),
    ("address_base = 0", "address_base = 2", r"address_base = 2.*valid values: 0, 1"),
    ("address_base = 0", "address_base = true", r"address_base = True.*valid values: 0, 1"),
    ('unit = "kg"', 'unit = "lb"', r"unit = 'lb'.*valid values: kg, g, N"),
    ('type = "float32"', 'type = "float32"\nword_order = "ACBD"',
     r"word_order = 'ACBD'.*ABCD, CDAB, BADC, DCBA"),
    ("address = 0\n", "adress = 0\n", r"\[value\] adress: unknown key; valid keys: address"),
    ("address = 0\n", "", r"\[value\] address: missing; an integer in 0..65535"),
    ("address = 0\n", "address = -1\n", r"address = -1: must be an integer in 0..65535"),
    ("address = 0\n", 'address = "zero"\n', r"address = 'zero': must be an integer"),
    ('type = "float32"', 'type = "float32"\ndecimals = 2', r"apply to type = 'int32' only"),
    ('type = "float32"', 'type = "int32"', r"exactly one of decimals.*decimals_address"),
    ('unit = "kg"', 'unit = "kg"\nscale = 0', r"scale = 0: must be non-zero"),
    ('unit = "kg"', 'unit = "kg"\nmin = 3\nmax = -3', r"min must be below max"),
    ("stable_bit = 0", "stable_bit = 0\noverload_bit = 0", r"two meanings share one bit"),
    ("stable_bit = 0", "stable_bit = 16", r"stable_bit = 16: must be an integer in 0..15"),
    ("address = 2\n", "address = 1\n", r"\[value\] and \[status\].*overlap"),
    ('kind = "loadcell"', 'kind = "scale"', r"kind = 'scale'.*valid values: loadcell, servo"),
    ("[tare]", "[taare]", r"top level\] taare: unknown key"),
    ("value = 1\n", "value = 70000\n", r"\[tare\] value = 70000.*0..65535"),
    ("[value]", "[value", r"not valid TOML"),
])
def test_bad_map_files_get_errors_naming_file_key_and_valid_values(write_toml, old, new,
                                                                   expected):
    assert old in GOOD
    path = write_toml(GOOD.replace(old, new, 1), "bad.toml")
    with pytest.raises(HILConfigError, match=expected) as info:
        load_map(path)
    assert "bad.toml" in str(info.value)


def test_good_map_parses_and_one_based_addresses_shift(write_toml):
    m = load_map(write_toml(GOOD.replace("address_base = 0", "address_base = 1")
                            .replace("address = 0\n", "address = 1\n")
                            .replace("address = 2\n", "address = 3\n")))
    assert (m.value.address, m.status.address, m.tare.address) == (0, 2, 9)


def test_one_based_map_refuses_address_zero(write_toml):
    with pytest.raises(HILConfigError, match=r"address = 0: must be an integer in 1..65536"):
        load_map(write_toml(GOOD.replace("address_base = 0", "address_base = 1")))


def test_servo_setpoint_with_a_decimals_register_is_refused(write_toml):
    text = """
[device]
kind = "servo"
function = "holding"
address_base = 0
[setpoint]
address = 0
type = "int32"
decimals_address = 4
unit = "deg"
"""
    with pytest.raises(HILConfigError, match=r"\[setpoint\] decimals_address.*fixed decimals"):
        load_map(write_toml(text))


def test_unknown_map_name_lists_the_shipped_ones():
    with pytest.raises(HILConfigError, match="no such file.*loadcell-float32-abcd"):
        load_map("loadcell-does-not-exist")


def test_float32_nan_decodes_to_nan_for_the_range_check():
    f = field(ValueType.FLOAT32, WordOrder.ABCD)
    regs = list(struct.unpack(">HH", struct.pack(">f", math.nan)))
    assert math.isnan(decode_value(f, regs))
