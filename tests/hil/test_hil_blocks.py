"""LoadCell and Servo against the emulator: sensible values, clamping, faults, recovery, close."""
from __future__ import annotations

import math
import threading
import time

import pytest
from featherstar.cosim.framework.block import Block
from featherstar.hil.blocks import LoadCell, Servo
from featherstar.hil.emulator import start_emulator
from featherstar.hil.errors import DeviceFault, Fault, HILConfigError, HILError

pytestmark = pytest.mark.hil
# Generous: a loaded 2-core machine can stall the emulator thread for tens of ms. Tests of
# timeouts set their own.
T = 1.0


def test_blocks_satisfy_the_block_protocol_with_the_simulated_ports(emulator):
    cell = LoadCell("cell", emulator.loadcell_url, timeout_s=T)
    servo = Servo("servo", emulator.servo_url, timeout_s=T)
    assert isinstance(cell, Block) and isinstance(servo, Block)
    assert list(cell.inputs) == [] and list(cell.outputs) == ["thrust_N", "t_read_s"]
    assert list(servo.inputs) == ["setpoint_rad"]
    assert list(servo.outputs) == ["angle_rad", "rate_rad_s", "accel_rad_s2"]
    assert cell.outputs["thrust_N"].unit == "N"
    with pytest.raises(HILError, match="not started"):
        cell.get_outputs()


def test_bad_block_configuration_fails_before_any_io():
    with pytest.raises(HILConfigError, match="safe_rad=2.0 outside limits"):
        Servo("servo", "modbus-tcp://127.0.0.1:1", safe_rad=2.0)
    with pytest.raises(HILConfigError, match="servo-default.toml.*kind = 'loadcell'"):
        LoadCell("cell", "modbus-tcp://127.0.0.1:1", "servo-default")
    with pytest.raises(HILConfigError, match="timeout_s must be positive"):
        LoadCell("cell", "modbus-tcp://127.0.0.1:1", timeout_s=0)


@pytest.mark.parametrize("lc_map", ["loadcell-float32-abcd", "loadcell-int32-cdab"])
def test_blocks_read_sensible_values_from_a_flapping_feather(make_emulator, lc_map):
    emu = make_emulator(loadcell_map=lc_map, seed=1)
    cell = LoadCell("cell", emu.loadcell_url, lc_map, timeout_s=T)
    servo = Servo("servo", emu.servo_url, timeout_s=T)
    cell.start(0.0)
    servo.start(0.0)
    try:
        assert abs(cell.get_outputs()["thrust_N"]) < 0.05      # tared at rest
        h, t, t0 = 0.005, 0.0, time.monotonic()
        thrust, angle, rate = [], [], []
        while t < 1.0:
            servo.set_inputs({"setpoint_rad": 0.6 * math.sin(2 * math.pi * 1.5 * t)})
            servo.do_step(t, h)
            cell.do_step(t, h)
            t += h
            time.sleep(max(0.0, t0 + t - time.monotonic()))
            thrust.append(cell.get_outputs()["thrust_N"])
            angle.append(servo.get_outputs()["angle_rad"])
            rate.append(servo.get_outputs()["rate_rad_s"])
        # A 12 x 7.5 cm plate flapped at +-0.6 rad, 1.5 Hz: about a newton, both signs. A
        # stalled test process catches up in a burst of steps, which the servo feels as a
        # setpoint step: spikes of several N, so only the bulk is bounded tightly.
        assert max(thrust) > 0.1 and min(thrust) < -0.1
        assert sorted(map(abs, thrust))[int(0.8 * len(thrust))] < 3.0
        assert max(map(abs, thrust)) < 29.4          # never beyond the cell's capacity
        assert 0.3 < max(angle) < 0.65 and -0.65 < min(angle) < -0.3
        assert servo.estimate_source == "readback"
        # the rate is a difference over read times: two reads of a catching-up burst, close
        # together, amplify the read-back's quantisation (22 rad/s seen on a loaded PC)
        assert sorted(map(abs, rate))[int(0.8 * len(rate))] < 7.0
    finally:
        servo.close()
        cell.close()


def test_setpoints_are_clamped_to_limits_and_rate(emulator):
    servo = Servo("servo", emulator.servo_url, limits_rad=(-1.0, 0.5), rate_limit_rad_s=2.0,
                  timeout_s=T)
    servo.start(0.0)
    try:
        servo.set_inputs({"setpoint_rad": 3.0})
        servo.do_step(0.0, 0.01)
        assert servo.command_rad == pytest.approx(0.02)            # 2 rad/s * 10 ms
        assert emulator.emulator.servo_setpoint_rad == pytest.approx(0.02, abs=1e-4)
        for k in range(1, 40):
            servo.do_step(0.01 * k, 0.01)
        assert servo.command_rad == pytest.approx(0.5)              # then the upper limit
        servo.set_inputs({"setpoint_rad": -5.0})
        servo.do_step(0.4, 1.0)
        assert servo.command_rad == pytest.approx(-1.0)
        with pytest.raises(HILError, match="not finite"):
            servo.set_inputs({"setpoint_rad": math.nan})
        with pytest.raises(HILError, match="unknown inputs"):
            servo.set_inputs({"setpoint_deg": 1.0})
    finally:
        servo.close()


def test_default_limits_are_mg996r_like(emulator):
    servo = Servo("servo", emulator.servo_url, timeout_s=T)
    assert servo.limits_rad == pytest.approx((-math.pi / 2, math.pi / 2))
    assert servo.rate_limit_rad_s == pytest.approx(6.2)


def test_servo_without_readback_estimates_from_the_setpoint(make_emulator, write_toml):
    path = write_toml("""
[device]
kind = "servo"
function = "holding"
address_base = 0
[setpoint]
address = 0
type = "float32"
unit = "rad"
""")
    emu = make_emulator(servo_map=path)
    servo = Servo("servo", emu.servo_url, path, rate_limit_rad_s=1.0, timeout_s=T)
    servo.start(0.0)
    try:
        assert servo.estimate_source == "setpoint"
        servo.set_inputs({"setpoint_rad": 1.0})
        servo.do_step(0.0, 0.1)
        assert servo.get_outputs() == pytest.approx(
            {"angle_rad": 0.1, "rate_rad_s": 1.0, "accel_rad_s2": 10.0})
        servo.do_step(0.1, 0.1)
        assert servo.get_outputs() == pytest.approx(
            {"angle_rad": 0.2, "rate_rad_s": 1.0, "accel_rad_s2": 0.0})
    finally:
        servo.close()


def test_close_commands_the_safe_position_when_the_link_is_up(emulator):
    servo = Servo("servo", emulator.servo_url, safe_rad=0.25, timeout_s=T)
    servo.start(0.0)
    servo.set_inputs({"setpoint_rad": -0.5})
    servo.do_step(0.0, 1.0)
    assert emulator.emulator.servo_setpoint_rad == pytest.approx(-0.5, abs=1e-4)
    servo.close()
    assert emulator.emulator.servo_setpoint_rad == pytest.approx(0.25, abs=1e-4)
    servo.close()        # idempotent


@pytest.mark.realtime   # wall-clock bounds with >= 3x margin; pass under two busy processes
def test_close_never_raises_when_the_link_is_down_and_gives_up_at_its_deadline(make_emulator):
    emu = make_emulator()
    servo = Servo("servo", emu.servo_url, timeout_s=T, safe_timeout_s=0.5)
    servo.start(0.0)
    emu.stop()
    t = time.monotonic()
    servo.close()
    # It keeps trying (the device may come back) until safe_timeout_s, then reports failure.
    assert 0.4 < time.monotonic() - t < 3.0
    assert servo.safe_confirmed is False


def test_lost_emulator_raises_a_fault_naming_device_fault_and_time(make_emulator):
    emu = make_emulator()
    cell = LoadCell("thrust-cell", emu.loadcell_url, timeout_s=T)
    cell.start(0.0)
    cell.do_step(0.0, 0.01)
    emu.stop()
    with pytest.raises(DeviceFault) as info:
        cell.do_step(0.01, 0.01)
    assert info.value.fault in (Fault.LINK_LOST, Fault.CONNECT, Fault.TIMEOUT)
    assert info.value.device == "thrust-cell" and info.value.t_s == pytest.approx(0.02)
    assert "thrust-cell" in str(info.value) and "t=0.0200 s" in str(info.value)
    cell.close()


@pytest.mark.realtime   # wall-clock bounds with >= 3x margin; pass under two busy processes
def test_reconnects_when_the_emulator_comes_back_within_reconnect_s(make_emulator):
    emu = make_emulator(seed=2)
    port = emu.port
    cell = LoadCell("cell", emu.loadcell_url, reconnect_s=5.0, tare_on_start=False,
                    timeout_s=T)
    servo = Servo("servo", emu.servo_url, reconnect_s=5.0, timeout_s=T)
    cell.start(0.0)
    servo.start(0.0)
    emu.stop()
    revived = []
    timer = threading.Timer(0.3, lambda: revived.append(start_emulator(port=port, seed=3)))
    timer.start()
    try:
        t = time.monotonic()
        cell.do_step(0.0, 0.01)
        servo.set_inputs({"setpoint_rad": 0.2})
        servo.do_step(0.0, 1.0)
        assert 0.2 < time.monotonic() - t < 5.0
        assert math.isfinite(cell.get_outputs()["thrust_N"])
        # A fresh device lost its enable: the servo re-sends it after the reconnect.
        assert revived[0].emulator.servo_enabled
        assert revived[0].emulator.servo_setpoint_rad == pytest.approx(0.2, abs=1e-4)
    finally:
        timer.join()
        servo.close()
        cell.close()
        for handle in revived:
            handle.stop()


@pytest.mark.realtime   # wall-clock bounds with >= 3x margin; pass under two busy processes
def test_recovery_is_bounded_by_reconnect_s(make_emulator):
    emu = make_emulator()
    cell = LoadCell("cell", emu.loadcell_url, reconnect_s=0.3, timeout_s=T)
    cell.start(0.0)
    emu.stop()
    t = time.monotonic()
    with pytest.raises(DeviceFault, match="not cleared within reconnect_s=0.3"):
        cell.do_step(1.0, 0.01)
    assert 0.25 < time.monotonic() - t < 1.5
    cell.close()


@pytest.mark.realtime   # wall-clock bounds with >= 3x margin; pass under two busy processes
@pytest.mark.parametrize("fault, expected, kwargs", [
    ("silent", Fault.TIMEOUT, {}),
    ("exception", Fault.EXCEPTION_RESPONSE, {}),
    ("overload", Fault.OVERLOAD, {}),
    ("error", Fault.DEVICE_ERROR, {}),
    ("freeze", Fault.STALE, {"stale_s": 0.1}),
])
def test_injected_loadcell_faults_raise(emulator, fault, expected, kwargs):
    cell = LoadCell("cell", emulator.loadcell_url, timeout_s=0.03 if fault == "silent" else T,
                    **kwargs)
    cell.start(0.0)
    emulator.emulator.inject("loadcell", fault)
    t = time.monotonic()
    with pytest.raises(DeviceFault) as info:
        for k in range(200):
            cell.do_step(0.01 * k, 0.01)
            time.sleep(0.005)
    assert info.value.fault is expected
    assert time.monotonic() - t < 1.0
    if fault == "exception":
        assert "code 4 (DEVICE_FAILURE)" in str(info.value)
    emulator.emulator.inject("loadcell", None)
    cell.close()


def test_transient_fault_is_ridden_out_with_reconnect_s(emulator):
    cell = LoadCell("cell", emulator.loadcell_url, timeout_s=0.03, reconnect_s=2.0)
    cell.start(0.0)
    emulator.emulator.inject("loadcell", "silent")
    timer = threading.Timer(0.2, emulator.emulator.inject, ("loadcell", None))
    timer.start()
    try:
        cell.do_step(0.0, 0.01)
        cell.do_step(0.01, 0.01)    # and the late reply is not taken as this answer
        assert abs(cell.get_outputs()["thrust_N"]) < 0.1
    finally:
        timer.join()
        cell.close()


def test_reading_beyond_the_map_range_is_a_fault(make_emulator, constant_plant, write_toml):
    path = write_toml("""
[device]
kind = "loadcell"
function = "input"
address_base = 0
[value]
address = 0
type = "float32"
unit = "g"
min = -100.0
max = 100.0
""")
    emu = make_emulator(loadcell_map=path, plant=constant_plant(thrust_N=2.0), noise_N=0.0)
    cell = LoadCell("cell", emu.loadcell_url, path, tare_on_start=False, timeout_s=T)
    with pytest.raises(DeviceFault, match=r"out_of_range.*reads 173.3\d* g, outside the map's "
                                          r"range \[-100.0, 100.0\]"):
        cell.start(0.0)
    cell.close()


def test_overloaded_cell_sets_the_overload_bit(make_emulator, constant_plant):
    emu = make_emulator(plant=constant_plant(thrust_N=40.0), noise_N=0.0)
    cell = LoadCell("cell", emu.loadcell_url, tare_on_start=False, timeout_s=T)
    with pytest.raises(DeviceFault, match="overload"):
        cell.start(0.0)
    cell.close()


def test_unit_mismatch_gives_an_exception_response_not_garbage(emulator):
    cell = LoadCell("cell", emulator.servo_url, timeout_s=T)   # the servo has no input regs
    with pytest.raises(DeviceFault, match="exception_response.*ILLEGAL_ADDRESS"):
        cell.start(0.0)
    cell.close()


def test_servo_error_bit_is_a_device_error(emulator):
    servo = Servo("servo", emulator.servo_url, timeout_s=T)
    servo.start(0.0)
    emulator.emulator.inject("servo", "error")
    with pytest.raises(DeviceFault, match="device_error.*servo controller error bit"):
        servo.do_step(0.0, 0.01)
    emulator.emulator.inject("servo", None)
    servo.close()
    assert emulator.emulator.servo_setpoint_rad == 0.0     # the link was up: safe sent


def test_a_cell_never_stable_for_unstable_s_is_stale(make_emulator, constant_plant):
    class Drifting(constant_plant):
        def advance(self, dt_s: float) -> None:
            self.angle_rad += 1.0 * dt_s          # always moving: never "stable"

    emu = make_emulator(plant=Drifting())
    cell = LoadCell("cell", emu.loadcell_url, timeout_s=T, unstable_s=0.1)
    cell.start(0.0)
    with pytest.raises(DeviceFault, match=r"stale.*not stable for 0\.1"):
        for k in range(100):
            cell.do_step(0.01 * k, 0.01)
            time.sleep(0.01)
    assert not cell.status.stable
    cell.close()


@pytest.mark.realtime   # wall-clock bounds with >= 3x margin; pass under two busy processes
@pytest.mark.hil
def test_start_is_patient_but_the_run_keeps_its_step_deadline(make_emulator):
    """A transmitter slow to answer its first requests (here 0.3 s) does not fail the start
    with a 50 ms step timeout; once started, a silent device is a fault within that timeout."""
    emu = make_emulator(seed=5)
    cell = LoadCell("cell", emu.loadcell_url, timeout_s=0.05, start_timeout_s=1.0)
    emu.emulator.inject("loadcell", "silent")
    healer = threading.Timer(0.3, emu.emulator.inject, ("loadcell", None))
    healer.start()
    try:
        t0 = time.monotonic()
        cell.start(0.0)
        assert 0.25 < time.monotonic() - t0 < 5.0
        assert cell.link.timeout_s == pytest.approx(0.05)   # restored for the run
        assert cell.events == []                             # start-up slowness is not a gap
        emu.emulator.inject("loadcell", "silent")
        t0 = time.monotonic()
        with pytest.raises(DeviceFault) as info:
            cell.do_step(0.0, 0.004)
        assert info.value.fault is Fault.TIMEOUT and time.monotonic() - t0 < 1.0
    finally:
        healer.cancel()
        emu.emulator.inject("loadcell", None)
        cell.close()


@pytest.mark.hil
def test_a_recovered_fault_and_a_new_connection_are_events(make_emulator):
    emu = make_emulator(seed=6)
    cell = LoadCell("cell", emu.loadcell_url, timeout_s=0.05, reconnect_s=5.0)
    cell.start(0.0)
    try:
        emu.emulator.inject("loadcell", "silent")
        threading.Timer(0.2, emu.emulator.inject, ("loadcell", None)).start()
        cell.do_step(0.0, 0.004)
        kinds = [e["kind"] for e in cell.events]
        assert "gap" in kinds and "reconnect" in kinds   # a timeout re-dials the link
        reconnect = next(e for e in cell.events if e["kind"] == "reconnect")
        assert reconnect["tare_unknown"] is True and reconnect["t_s"] == pytest.approx(0.004)
    finally:
        cell.close()


@pytest.mark.parametrize("late_reads", [(0,), (0, 1), (3,), ()])
def test_read_times_are_anchored_on_the_most_punctual_read(emulator, monkeypatch, late_reads):
    # The PC's clock is the test's: step k's read comes at its step's end, 10 ms * (k + 1), except
    # those made 11 ms late; a read after a late one comes no earlier than 0.1 ms after it.
    # Anchored on the first read, a late first read stamped every later sample 11 ms early, and a
    # streamed record ended short of its run (a bench study stopped on it under load).
    cell = LoadCell("cell", emulator.loadcell_url, timeout_s=T)
    cell.start(0.0)
    origin_s, h_s, late_s = time.monotonic(), 0.01, 0.011
    stamps, read_at = [], origin_s
    try:
        for k in range(6):
            read_at = max(read_at + 1e-4, origin_s + (k + 1) * h_s + (late_s if k in late_reads else 0.0))
            monkeypatch.setattr("featherstar.hil.blocks.time.monotonic", lambda: read_at)
            cell.do_step(k * h_s, h_s)
            stamps.append(cell.get_outputs()["t_read_s"])
    finally:
        monkeypatch.undo()
        cell.close()
    on_time = [k for k in range(6) if k > max(late_reads, default=-1) + 1]   # caught up by then
    for k in on_time:      # every read after the first punctual one: stamped at its step's time
        assert stamps[k] == pytest.approx((k + 1) * h_s, abs=1e-9)
    assert stamps[-1] >= 6 * h_s - 1e-9     # the record reaches the end of the run
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
