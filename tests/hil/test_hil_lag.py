"""An emulator whose plant falls behind real time says so (status lag bit), and the run knows.

A plant that takes longer to advance than the wall-clock time it advances serves stale states
the client cannot tell from fresh ones; the emulator sets the lag bit of both devices' status
words until each has been read once, the hardware blocks note a "lag" event, and the master
excludes the period (featherstar.cosim.swimmer.validity).
"""
from __future__ import annotations

import time

import pytest
from featherstar.cosim.swimmer.validity import judge_periods
from featherstar.hil.blocks import LoadCell, Servo
from featherstar.hil.codec import decode_status
from featherstar.hil.emulated_bench import LAG_LIMIT_S, LOADCELL_UNIT
from featherstar.hil.plant import FlatPlatePlant
from pymodbus.client import ModbusTcpClient

# Lag is wall-clock behaviour by definition; the limits have margins (pass under two busy processes).
pytestmark = [pytest.mark.hil, pytest.mark.realtime]


class SlowPlant(FlatPlatePlant):
    """A flat plate whose advance costs `cost_s` of wall-clock time once `slow` is set."""

    slow = False
    cost_s = 2 * LAG_LIMIT_S

    def advance(self, dt_s: float) -> None:
        if self.slow:
            time.sleep(self.cost_s)
        super().advance(dt_s)


def _step_blocks(cell: LoadCell, servo: Servo, t_s: float, n: int, h_s: float = 0.005) -> float:
    for _ in range(n):
        servo.set_inputs({"setpoint_rad": 0.3})
        servo.do_step(t_s, h_s)
        cell.do_step(t_s, h_s)
        t_s += h_s
    return t_s


def test_a_plant_behind_real_time_sets_the_lag_bit_and_the_period_is_excluded(make_emulator):
    plant = SlowPlant()
    emu = make_emulator(plant=plant, seed=1)
    cell, servo = LoadCell("cell", emu.loadcell_url, timeout_s=1.0), Servo("servo", emu.servo_url, timeout_s=1.0)
    cell.start(0.0)
    servo.start(0.0)
    try:
        t = _step_blocks(cell, servo, 0.0, 20)
        assert not [e for e in cell.events + servo.events if e["kind"] == "lag"]
        assert emu.emulator.lag_events == 0
        plant.slow = True
        t = _step_blocks(cell, servo, t, 3)
        plant.slow = False
        lagged_at = t
        t = _step_blocks(cell, servo, t, 20)
    finally:
        servo.close()
        cell.close()
    assert emu.emulator.lag_events >= 1 and emu.emulator.worst_lag_s >= LAG_LIMIT_S
    lags = [e for e in cell.events + servo.events if e["kind"] == "lag"]
    # Both devices saw it, while it lasted (the bit is cleared when read, and set again by
    # every slow advance).
    assert {e["device"] for e in lags} == {"cell", "servo"}
    assert all(0.1 < e["t_s"] <= lagged_at + 0.01 for e in lags)
    verdicts = judge_periods([0.0, 0.3], 0.1, 3, 0.005, [], lags)
    assert not verdicts[0].reasons and any("behind real time" in r for r in verdicts[1].reasons)
    assert not verdicts[2].reasons


def _hold_the_emulator(emu, hold_s: float = 3 * LAG_LIMIT_S) -> None:
    """Hold the emulator's lock (it can neither tick nor answer meanwhile), then wait for the
    late tick to report it (a loaded machine may take a while to schedule it)."""
    with emu.emulator.lock:
        time.sleep(hold_s)
    deadline = time.monotonic() + 5.0
    while emu.emulator.lag_events == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert emu.emulator.lag_events > 0


def test_a_stalled_event_loop_sets_the_lag_bit(make_emulator):
    emu = make_emulator(seed=1)
    cell = LoadCell("cell", emu.loadcell_url, timeout_s=1.0)
    cell.start(0.0)
    try:
        cell.do_step(0.0, 0.005)
        assert not cell.status.lagging
        _hold_the_emulator(emu)
        cell.do_step(0.005, 0.005)
        assert cell.status.lagging
        cell.do_step(0.010, 0.005)
        assert not cell.status.lagging     # reported once, then cleared
    finally:
        cell.close()
    assert [e["t_s"] for e in cell.events if e["kind"] == "lag"] == [0.010]


def test_a_lag_report_waits_for_a_read_that_returns_the_status_word(make_emulator):
    emu = make_emulator(seed=1)
    status = emu.emulator.loadcell_map.status       # float32 map: value at 0-1, status at 2
    with ModbusTcpClient("127.0.0.1", port=emu.port, timeout=1, retries=0) as client:
        _hold_the_emulator(emu)
        client.read_input_registers(0, count=2, device_id=LOADCELL_UNIT)           # value only
        word = client.read_input_registers(status.address, count=1, device_id=LOADCELL_UNIT).registers[0]
        assert decode_status(status, word).lagging
        word = client.read_input_registers(status.address, count=1, device_id=LOADCELL_UNIT).registers[0]
        assert not decode_status(status, word).lagging
