"""Modbus RTU end to end: the emulator on one end of a pseudo-terminal pair, frames and the
hardware blocks on the other."""
from __future__ import annotations

import math
import os
import select
import struct
import time
import tty

import numpy as np
import pytest
from featherstar.cosim.scenes import load_scene
from featherstar.cosim.swimmer.run import run_scene
from featherstar.hil.blocks import LoadCell, Servo
from featherstar.hil.cli import main as cli_main
from featherstar.hil.emulator import spawn_emulator
from featherstar.hil.errors import DeviceFault
from featherstar.hil.hardware import split_url, with_hardware
from featherstar.hil.rtu_server import GAP_MIN_S, crc16, frame
from featherstar.hil.timed_run import run_bench_scene
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.hil
T = 1.0
# Longer than the server's silence, so a frame it would answer has been answered.
QUIET_S = 4 * GAP_MIN_S


def test_crc_matches_the_specification_example():
    # MODBUS over Serial Line V1.02, and every RTU trace: read 10 holding registers of unit 1.
    assert frame(1, bytes.fromhex("030000000A")) == bytes.fromhex("01 03 00 00 00 0A C5 CD")


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 255), st.binary(min_size=1, max_size=253), st.data())
def test_any_single_bit_error_breaks_the_crc(unit, pdu, data):
    adu = frame(unit, pdu)
    assert crc16(adu) == 0                     # the residue of a correct frame
    bit = data.draw(st.integers(0, 8 * len(adu) - 1))
    bad = bytearray(adu)
    bad[bit // 8] ^= 1 << (bit % 8)
    assert crc16(bytes(bad[:-2])) != int.from_bytes(bad[-2:], "little")


@pytest.fixture
def line(make_emulator):
    """(emulator, client fd): the emulator serves the master end of a fresh pty pair."""
    master, slave = os.openpty()
    tty.setraw(slave)
    emu = make_emulator(seed=0, rtu=master)
    yield emu, slave
    emu.stop()
    os.close(slave)
    os.close(master)


def _exchange(fd: int, request: bytes, expect: int | None, wait_s: float = T) -> bytes:
    """Send `request`; read `expect` bytes (or whatever arrives within QUIET_S if None)."""
    os.write(fd, request)
    reply = b""
    deadline = time.monotonic() + (wait_s if expect else QUIET_S)
    while (expect is None or len(reply) < expect) and time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        if ready:
            reply += os.read(fd, 512)
    return reply


def _read_request(unit: int, address: int, count: int, fc: int = 3) -> bytes:
    return frame(unit, struct.pack(">BHH", fc, address, count))


def test_the_emulator_answers_rtu_frames_with_unit_and_crc(line):
    _, fd = line
    reply = _exchange(fd, _read_request(2, 2, 2), 9)      # servo position, 2 registers
    assert reply[:3] == bytes([2, 3, 4]) and crc16(reply) == 0
    # Two requests in one burst are framed by their lengths and answered in order.
    reply = _exchange(fd, _read_request(2, 2, 2) + _read_request(2, 4, 1), 9 + 7)
    assert reply[:3] == bytes([2, 3, 4]) and crc16(reply[:9]) == 0
    assert reply[9:12] == bytes([2, 3, 2]) and crc16(reply[9:]) == 0
    # The shared PDU handler's exceptions travel too: a register the servo lacks.
    reply = _exchange(fd, _read_request(2, 60000, 1), 5)
    assert reply[:3] == bytes([2, 0x83, 0x02]) and crc16(reply) == 0
    # An unknown function code has no length rule: it ends at the silence, then is refused.
    reply = _exchange(fd, frame(2, bytes([0x41, 1, 2, 3])), 5)
    assert reply[:3] == bytes([2, 0xC1, 0x01]) and crc16(reply) == 0


def _holds_a_frame(data: bytes) -> bool:
    return any(crc16(data[i:j]) == 0 for i in range(len(data)) for j in range(i + 4, len(data) + 1))


def _flip(adu: bytes, bit: int) -> bytes:
    bad = bytearray(adu)
    bad[bit // 8] ^= 1 << (bit % 8)
    return bytes(bad)


# Line noise: random bytes, or a request to a served unit with one bit flipped anywhere.
NOISE = st.one_of(st.binary(min_size=1, max_size=40),
                  st.builds(_flip, st.sampled_from([_read_request(2, 2, 2),
                                                    frame(1, bytes.fromhex("0600010001"))]),
                            st.integers(0, 63)))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(garbage=NOISE, cuts=st.sets(st.integers(1, 7), max_size=3))
def test_after_any_line_noise_and_a_silence_a_request_split_anyhow_is_answered_once(line, garbage,
                                                                                    cuts):
    # Noise (a bad CRC, a collision, another slave's garbled reply) is never answered and
    # never swallows the next request; the request arrives in arbitrary bursts.
    assume(not _holds_a_frame(garbage))
    _, fd = line
    assert _exchange(fd, garbage, None) == b""
    request = _read_request(2, 2, 2)
    bounds = [0, *sorted(cuts), len(request)]
    for start, end in zip(bounds[:-1], bounds[1:-1]):
        os.write(fd, request[start:end])
    reply = _exchange(fd, request[bounds[-2]:], 9)
    assert reply[:3] == bytes([2, 3, 4]) and crc16(reply) == 0
    assert _exchange(fd, b"", None) == b""        # answered once


def test_other_units_get_no_answer_and_broadcast_writes_execute_silently(line):
    emu, fd = line
    assert _exchange(fd, _read_request(7, 2, 2), None) == b""    # another slave's request
    # Broadcast: enable the servo (register 5) on unit 0: executed, never answered.
    before = _exchange(fd, _read_request(2, 5, 1), 7)
    assert _exchange(fd, frame(0, struct.pack(">BHH", 6, 5, 1 - before[4])), None) == b""
    after = _exchange(fd, _read_request(2, 5, 1), 7)
    assert after[3:5] == bytes([0, 1 - before[4]])


def test_blocks_read_and_write_through_rtu(make_emulator):
    emu = make_emulator(seed=1, rtu="pty")
    assert emu.loadcell_url.startswith("modbus-rtu:///dev/")
    cell = LoadCell("cell", emu.loadcell_url, timeout_s=T)
    servo = Servo("servo", emu.servo_url, timeout_s=T)
    cell.start(0.0)
    servo.start(0.0)
    try:
        assert abs(cell.get_outputs()["thrust_N"]) < 0.05      # tared at rest
        h, t, t0 = 0.005, 0.0, time.monotonic()
        thrust, angle = [], []
        while t < 1.0:
            servo.set_inputs({"setpoint_rad": 0.6 * math.sin(2 * math.pi * 1.5 * t)})
            servo.do_step(t, h)
            cell.do_step(t, h)
            t += h
            time.sleep(max(0.0, t0 + t - time.monotonic()))
            thrust.append(cell.get_outputs()["thrust_N"])
            angle.append(servo.get_outputs()["angle_rad"])
        # The same bounds as over TCP (test_hil_blocks): a flapping plate, about a newton.
        assert max(thrust) > 0.1 and min(thrust) < -0.1
        assert max(map(abs, thrust)) < 29.4
        assert 0.3 < max(angle) < 0.65 and -0.65 < min(angle) < -0.3
        assert servo.estimate_source == "readback"
    finally:
        servo.close()
        cell.close()


def test_featherstar_emulate_serves_rtu_on_a_pty_and_a_killed_one_is_a_fault():
    emu = spawn_emulator(plant="flat-plate", seed=0, rtu="pty")
    try:
        assert emu.loadcell_url.startswith("modbus-rtu:///dev/")
        cell = LoadCell("cell", emu.loadcell_url, timeout_s=0.2)
        cell.start(0.0)
        try:
            cell.do_step(0.0, 0.01)
            assert abs(cell.get_outputs()["thrust_N"]) < 0.05
            emu.kill()      # the device goes silent mid-run: no reply is a fault, not a hang
            with pytest.raises(DeviceFault):
                cell.do_step(0.01, 0.01)
        finally:
            cell.close()
    finally:
        emu.stop()


def test_hardware_urls_keep_the_empty_host_of_an_rtu_url():
    # urlunsplit would print modbus-rtu:/dev/ttyUSB0, which no device URL parser accepts.
    assert split_url("servo", "modbus-rtu:///dev/ttyUSB0?baudrate=115200&unit=2&timeout_s=0.1") \
        == ("modbus-rtu:///dev/ttyUSB0?baudrate=115200&unit=2", {"timeout_s": 0.1})


def test_the_testbed_runs_device_timed_over_rtu(make_emulator):
    # The devices keep the time, so this end-to-end run does not depend on the PC's scheduling.
    emu = make_emulator(seed=0, rtu="pty", noise_N=0.0)
    scene = with_hardware(load_scene("testbed"), {"servo": emu.servo_url + "&clock=device",
                                                  "loadcell": emu.loadcell_url + "&clock=device"})
    result = run_bench_scene(scene, {"feather.morphology": "plain", "master.periods": 3,
                                     "metrics.settle_periods": 1})
    summary = result.summary
    assert result.complete and summary["coupling"] == "device-timed"
    assert summary["validity"]["valid_periods"] == 2 and summary["validity"]["invalid_periods"] == []
    assert summary["samples"]["lost"] == {"servo": 0, "loadcell": 0}
    # the plain feather's symmetric stroke: thrust as much forward as back (TR 1)
    assert summary["thrust_ratio"] == pytest.approx(1.0, abs=0.02)
    thrust = result["loadcell_hw.thrust_N"]
    assert 1.0 < max(thrust) - min(thrust) < 29.4    # a flapping plate, within capacity


STREAMED_OVERSHOOT_S = 0.005   # streamed steps of 20 ms with ~7 ms of line time leave slack


@pytest.mark.realtime
def test_the_testbed_streams_over_rtu_when_the_machine_keeps_time(make_emulator, keeps_time, skip_if_time_was_lost):
    if keeps_time > STREAMED_OVERSHOOT_S:
        pytest.skip(f"the machine cannot keep 20 ms steps now: 5 ms sleeps overshoot by "
                    f"{keeps_time * 1e3:.1f} ms (p90; this test needs "
                    f"{STREAMED_OVERSHOOT_S * 1e3:.0f} ms)")
    emu = make_emulator(seed=0, rtu="pty", noise_N=0.0)
    # A reply that a busy moment delays past the step is a deadline miss, not a fault: the
    # transport is what is tested (the 50 ms default timeout failed once under two busy processes).
    margins = "&timeout_s=0.5&reconnect_s=3"
    scene = with_hardware(load_scene("testbed"), {"servo": emu.servo_url + "&safe_timeout_s=0.5" + margins,
                                                  "loadcell": emu.loadcell_url + margins})
    # 50 Hz, not the scene's 250 Hz: pymodbus' serial client polls for the end of a reply
    # every ms, so a request takes ~2.3 ms over a pty (0.2 ms over TCP), 3 of them per step.
    result = run_scene(scene, {"feather.morphology": "plain", "master.periods": 2,
                               "metrics.settle_periods": 1, "master.step_s": 0.02,
                               "master.check_steps": False})   # the transport is tested here
    stats = result.summary["stats"]
    thrust = result["loadcell_hw.thrust_N"]
    assert len(thrust) == stats["macro_steps"] + 1 and np.all(np.isfinite(thrust))
    # keeps_time is measured before the run; load that comes during it shows in the run's summary
    skip_if_time_was_lost(result.summary)
    assert result.complete and math.isfinite(result.summary["thrust_ratio"])


@pytest.mark.parametrize("path, why", [("/dev/null", "not a serial line"),
                                       ("/nonexistent/tty", "cannot open")])
def test_emulate_refuses_a_path_that_is_no_serial_line_before_any_work(capsys, path, why):
    with pytest.raises(SystemExit) as info:
        cli_main(["emulate", "--rtu", path])      # default fmu plant: refused before the build
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--rtu {path}: {why}" in err


def test_a_flood_of_requests_is_answered_in_order_up_to_a_bound_and_the_line_survives(line):
    _, fd = line
    flood = b"".join(_read_request(2, 2, 2) for _ in range(200))
    os.write(fd, flood)
    replies = _exchange(fd, b"", None)
    while True:                      # drain what the server answered, however many
        more = _exchange(fd, b"", None)
        if not more:
            break
        replies += more
    n = len(replies) // 9
    assert 16 <= n < 200 and len(replies) == 9 * n      # the bounded queue dropped the rest
    assert all(replies[9 * i:9 * i + 3] == bytes([2, 3, 4]) for i in range(n))
    assert len(_exchange(fd, _read_request(2, 2, 2), 9)) == 9
