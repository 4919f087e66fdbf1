"""Every register-map option through a real server on an ephemeral loopback port: the
emulator encodes, the blocks decode (load cell, servo position) and the reverse (setpoint)."""
from __future__ import annotations

import itertools

import pytest

from featherstar.hil.blocks import LoadCell, Servo
from featherstar.hil.emulated_bench import REGISTER_DECIMALS

pytestmark = pytest.mark.hil
# Generous: a loaded 2-core machine can stall the emulator thread for tens of ms. Tests of
# timeouts set their own.
T = 1.0

ORDERS = ["ABCD", "CDAB", "BADC", "DCBA"]
TYPES = {"float32": 'type = "float32"',
         "int32-fixed": 'type = "int32"\ndecimals = 4',
         "int32-register": 'type = "int32"\ndecimals_address = {dec}'}


def number(kind: str, order: str, base: int, address: int, unit: str, scale: float,
           offset: float) -> str:
    spec = TYPES[kind].format(dec=base + address + 2)
    return (f'address = {base + address}\n{spec}\nword_order = "{order}"\nunit = "{unit}"\n'
            f"scale = {scale}\noffset = {offset}\n")


def tolerance(kind: str, decimals: int, scale: float, to_si: float) -> float:
    if kind == "float32":
        return 1e-5
    return (0.5 * 10.0**-decimals * abs(scale) + 1e-9) * to_si


@pytest.mark.parametrize("kind, order, function, base", list(itertools.product(
    TYPES, ORDERS, ["holding", "input"], [0, 1])))
def test_loadcell_map_options_round_trip(make_emulator, constant_plant, write_toml, kind,
                                         order, function, base):
    scale, offset = (-1.0, 0.0) if base else (0.5, 0.125)
    path = write_toml(f"""
[device]
kind = "loadcell"
function = "{function}"
address_base = {base}
[value]
{number(kind, order, base, 4, "kg", scale, offset)}
[status]
address = {base + 7}
stable_bit = 0
overload_bit = 5
error_bit = 9
[tare]
address = {base + 20}
value = 7
""")
    emu = make_emulator(loadcell_map=path, noise_N=0.0, plant=constant_plant(thrust_N=1.2345))
    cell = LoadCell("cell", emu.loadcell_url, path, tare_on_start=False, timeout_s=T)
    cell.start(0.0)
    try:
        decimals = 4 if kind == "int32-fixed" else REGISTER_DECIMALS
        assert cell.get_outputs()["thrust_N"] == pytest.approx(
            emu.emulator.force_N(), abs=tolerance(kind, decimals, scale, 9.80665))
        assert cell.status.stable and not cell.status.overload
        cell.tare(0.0)          # the command register round-trips too
        assert emu.emulator.tare_N == pytest.approx(emu.emulator.force_N())
    finally:
        cell.close()


@pytest.mark.parametrize("kind, order, base", [
    (k, o, b) for (k, o), b in zip(itertools.product(TYPES, ORDERS), itertools.cycle([0, 1]))])
def test_servo_map_options_round_trip(make_emulator, constant_plant, write_toml, kind, order,
                                      base):
    setpoint_kind = "int32-fixed" if kind == "int32-register" else kind
    path = write_toml(f"""
[device]
kind = "servo"
function = "{'input' if base else 'holding'}"
address_base = {base}
[setpoint]
{number(setpoint_kind, order, base, 0, "deg", 1.0, 0.0)}
[position]
{number(kind, order, base, 4, "rad" if base else "deg", -1.0 if base else 2.0, 0.0)}
[enable]
address = {base + 10}
value = 3
""")
    plant = constant_plant(angle_rad=0.4321)
    emu = make_emulator(servo_map=path, plant=plant)
    servo = Servo("servo", emu.servo_url, path, timeout_s=T)
    servo.start(0.0)
    try:
        decimals = REGISTER_DECIMALS if kind == "int32-register" else 4
        to_si = 1.0 if base else 3.141592653589793 / 180
        scale = -1.0 if base else 2.0
        assert servo.get_outputs()["angle_rad"] == pytest.approx(
            0.4321, abs=tolerance(kind, decimals, scale, to_si))
        assert emu.emulator.servo_enabled
        servo.set_inputs({"setpoint_rad": -0.7654})
        servo.do_step(0.0, 1.0)     # long enough for the rate limit to reach the target
        assert servo.command_rad == pytest.approx(-0.7654)
        assert emu.emulator.servo_setpoint_rad == pytest.approx(
            -0.7654, abs=tolerance(setpoint_kind, 4, 1.0, 3.141592653589793 / 180))
        assert plant.setpoint_rad == emu.emulator.servo_setpoint_rad
    finally:
        servo.close()
