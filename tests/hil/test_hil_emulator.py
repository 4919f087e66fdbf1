"""The analytic plant, the emulator's device behaviour at register level, and the CLI."""
from __future__ import annotations

import argparse
import math

import pytest
from pymodbus.client import ModbusTcpClient

from featherstar.hil.cli import main, register
from featherstar.hil.emulator import LOADCELL_UNIT, SERVO_UNIT
from featherstar.hil.plant import FlatPlatePlant, Plant
from featherstar.hil.codec import encode_value
from featherstar.hil.registers import load_servo_map


def strip_thrust_N(p: FlatPlatePlant, n: int = 2000) -> float:
    """Midpoint-rule integral of the strip forces over the span, projected on the thrust axis."""
    dr = p.length_m / n
    total = 0.0
    for i in range(n):
        r = (i + 0.5) * dr
        added_mass = p.c_a * p.rho_kg_m3 * math.pi * p.width_m**2 / 4 * r * p.accel_rad_s2
        drag = 0.5 * p.rho_kg_m3 * p.c_n * p.width_m * abs(r * p.rate_rad_s) * r * p.rate_rad_s
        total -= (added_mass + drag) * dr
    return total * math.cos(p.angle_rad)


@pytest.mark.parametrize("angle, rate, accel", [(0.0, -3.0, 0.0), (0.4, 2.0, 50.0),
                                                (-0.7, -5.0, -120.0)])
def test_flat_plate_root_force_matches_strip_integration(angle, rate, accel):
    p = FlatPlatePlant(angle_rad=angle, rate_rad_s=rate, accel_rad_s2=accel)
    assert p.thrust_N == pytest.approx(strip_thrust_N(p), rel=1e-5)
    assert isinstance(p, Plant)


def test_plant_is_rate_limited_settles_and_a_downstroke_pushes_up():
    p = FlatPlatePlant()
    p.set_setpoint_rad(-1.2)
    thrust, rates = [], []
    for _ in range(400):
        p.advance(0.0025)
        thrust.append(p.thrust_N)
        rates.append(p.rate_rad_s)
    assert min(rates) >= -6.2 - 1e-9 and min(rates) < -6.0
    assert max(thrust) > 0.5                     # downstroke: positive thrust
    assert p.angle_rad == pytest.approx(-1.2, abs=1e-3) and abs(p.thrust_N) < 1e-3
    p.set_setpoint_rad(5.0)
    assert p.setpoint_rad == pytest.approx(math.pi / 2)


@pytest.mark.hil
def test_servo_follows_setpoints_only_once_enabled_and_refuses_half_writes(emulator):
    servo_map = load_servo_map("servo-default")
    sp = servo_map.setpoint
    with ModbusTcpClient("127.0.0.1", port=emulator.port, timeout=1, retries=0) as c:
        assert not c.write_registers(sp.address, encode_value(sp, 30.0),
                                     device_id=SERVO_UNIT).isError()
        assert emulator.emulator.plant.setpoint_rad == 0.0          # disabled: ignored
        c.write_register(servo_map.enable.address, servo_map.enable.value, device_id=SERVO_UNIT)
        c.write_registers(sp.address, encode_value(sp, 30.0), device_id=SERVO_UNIT)
        assert emulator.emulator.plant.setpoint_rad == pytest.approx(math.radians(30.0))
        half = c.write_register(sp.address + 1, 0, device_id=SERVO_UNIT)
        assert half.isError() and half.exception_code == 2
        readonly = c.write_registers(servo_map.position.address, [0, 0], device_id=SERVO_UNIT)
        assert readonly.isError() and readonly.exception_code == 2
        undefined = c.read_input_registers(0, count=2, device_id=SERVO_UNIT)
        assert undefined.isError() and undefined.exception_code == 2


@pytest.mark.hil
def test_tare_zeroes_the_load_cell(make_emulator, constant_plant):
    emu = make_emulator(plant=constant_plant(thrust_N=0.5), noise_N=0.0)
    with ModbusTcpClient("127.0.0.1", port=emu.port, timeout=1, retries=0) as c:
        def read_kg() -> float:
            regs = c.read_input_registers(0, count=2, device_id=LOADCELL_UNIT).registers
            return c.convert_from_registers(regs, c.DATATYPE.FLOAT32)
        assert read_kg() == pytest.approx((0.5 - 0.3) / 9.80665, rel=1e-6)
        c.write_register(10, 1, device_id=LOADCELL_UNIT)
        assert read_kg() == pytest.approx(0.0, abs=1e-7)


@pytest.mark.hil
def test_inject_refuses_unknown_faults(emulator):
    with pytest.raises(ValueError, match="fault one of"):
        emulator.emulator.inject("loadcell", "smoke")


def test_cli_registers_emulate_with_documented_options(capsys):
    parser = argparse.ArgumentParser(prog="featherstar")
    register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["emulate", "--port", "0", "--noise-N", "0.02", "--seed", "3",
                              "--loadcell-map", "loadcell-int32-cdab"])
    assert (args.port, args.noise_N, args.seed, args.host) == (0, 0.02, 3, "127.0.0.1")
    assert args.func.__name__ == "emulate"
    with pytest.raises(SystemExit) as info:
        parser.parse_args(["emulate", "--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    for option in ("--host", "--port", "--loadcell-map", "--servo-map", "--noise-N", "--seed",
                   "unit=1", "loadcell-float32-abcd"):
        assert option in text


def test_cli_reports_a_bad_map_and_exits_2(capsys):
    with pytest.raises(SystemExit) as info:
        main(["emulate", "--port", "0", "--servo-map", "no-such-map"])
    assert info.value.code == 2
    assert "no-such-map" in capsys.readouterr().err


@pytest.mark.parametrize("host", ["0.0.0.0", "192.168.1.20", "bench.example.org"])
def test_binding_beyond_loopback_needs_an_explicit_flag(capsys, host):
    with pytest.raises(SystemExit) as info:
        main(["emulate", "--port", "0", "--plant", "flat-plate", "--host", host])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert f"--host {host}" in err and "--allow-remote" in err


@pytest.mark.hil
def test_allow_remote_binds_with_a_warning(tmp_path):
    import subprocess
    import sys

    err_path = tmp_path / "stderr"
    with err_path.open("w") as err:
        proc = subprocess.Popen([sys.executable, "-m", "featherstar.hil", "emulate", "--host", "0.0.0.0",
                                 "--allow-remote", "--port", "0", "--plant", "flat-plate"],
                                stdout=subprocess.PIPE, stderr=err, text=True)
        try:
            assert "listening on modbus-tcp://0.0.0.0:" in proc.stdout.readline()
        finally:
            proc.terminate()
            proc.wait(10)
            proc.stdout.close()
    assert "WARNING: serving on 0.0.0.0" in err_path.read_text()


@pytest.mark.hil
def test_fmu_plant_reset_starts_fresh_instances_at_rest():
    from featherstar.hil.fmu_plant import FmuPlant

    plant = FmuPlant("plain")
    plant.set_setpoint_rad(0.5)
    plant.advance(0.2)
    moved = plant.angle_rad
    plant.reset()
    assert moved > 0.3 and abs(plant.angle_rad) < 1e-12 and abs(plant.thrust_N) < 1e-9   # at rest again
    plant.set_setpoint_rad(0.5)
    plant.advance(0.2)
    assert plant.angle_rad == pytest.approx(moved, rel=1e-9)   # the same physics again


@pytest.mark.parametrize("host, loopback", [("127.0.0.1", True), ("127.0.0.2", True),
                                            ("::1", True), ("localhost", True),
                                            ("0.0.0.0", False), ("::", False)])
def test_only_loopback_counts_as_local(host, loopback):
    from featherstar.hil.cli import is_loopback

    assert is_loopback(host) is loopback


class _SinePlant:
    """thrust = sin(2π·7 Hz·t) of its own time: the emulator's readings can be checked exactly."""

    angle_rad = 0.0

    def __init__(self) -> None:
        self.t_s = 0.0

    @property
    def thrust_N(self) -> float:
        return math.sin(2 * math.pi * 7.0 * self.t_s)

    @property
    def impulse_Ns(self) -> float:
        return (1.0 - math.cos(2 * math.pi * 7.0 * self.t_s)) / (2 * math.pi * 7.0)

    def set_setpoint_rad(self, x: float) -> None:
        pass

    def advance(self, dt_s: float) -> None:
        self.t_s += dt_s


def test_the_emulated_load_cell_integrates_like_a_sigma_delta_converter():
    """Each reading is the mean force since the previous one (so the readings' time integral is
    the plant's impulse, whatever the reading times), not the force at the reading's instant."""
    import time

    from featherstar.hil.emulator import Emulator
    from featherstar.hil.registers import load_loadcell_map

    plant = _SinePlant()
    emu = Emulator(load_loadcell_map("loadcell-float32-abcd"), load_servo_map("servo-default"), plant,
                   noise_N=0.0, preload_N=0.0, conversion_s=1.0)   # longer than any pause here
    emu.tick()
    assert emu.converted_force_N() == pytest.approx(plant.thrust_N, abs=1e-12)   # nothing to average yet
    integral_Ns, t_previous_s, impulse_previous_Ns = 0.0, plant.t_s, plant.impulse_Ns
    for pause_s in (0.021, 0.033, 0.025, 0.047):   # a tick advances the plant after TICK_S = 20 ms
        time.sleep(pause_s)
        emu.tick()
        reading_N = emu.converted_force_N()
        dt_s = plant.t_s - t_previous_s
        assert dt_s > 0
        assert reading_N == pytest.approx((plant.impulse_Ns - impulse_previous_Ns) / dt_s, abs=1e-9)
        assert emu.converted_force_N() == reading_N       # read again at once: the same conversion
        integral_Ns += reading_N * dt_s
        t_previous_s, impulse_previous_Ns = plant.t_s, plant.impulse_Ns
    assert integral_Ns == pytest.approx(plant.impulse_Ns - _SinePlant().impulse_Ns, abs=1e-12)


class _StepPlant(_SinePlant):
    """1 N for its first 0.1 s, then nothing."""

    @property
    def thrust_N(self) -> float:
        return 1.0 if self.t_s < 0.1 else 0.0

    @property
    def impulse_Ns(self) -> float:
        return min(self.t_s, 0.1)


def test_a_reading_after_a_pause_integrates_one_conversion_not_the_pause():
    """A tare after a rest reads the force now (the last conversion), not the rest's average:
    a servo that moved back to its safe position during the rest does not offset the next run."""
    import time

    from featherstar.hil.converter import CONVERSION_S
    from featherstar.hil.emulator import Emulator
    from featherstar.hil.registers import load_loadcell_map

    plant = _StepPlant()
    emu = Emulator(load_loadcell_map("loadcell-float32-abcd"), load_servo_map("servo-default"), plant,
                   noise_N=0.0, preload_N=0.0)
    emu.tick()
    emu.converted_force_N()
    while plant.t_s < 0.1 + 3 * CONVERSION_S:
        time.sleep(0.021)
        emu.tick()
    assert emu.converted_force_N() == pytest.approx(0.0, abs=1e-12)
