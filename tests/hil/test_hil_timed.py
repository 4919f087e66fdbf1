"""Device-timed runs on a device clock (deterministic): the emulated devices play and sample on
their own clock whatever the emulator's scheduling, the PC's ring reader counts overruns, and
the clock mapping undoes offset and drift."""
from __future__ import annotations

import asyncio
import math
import random
from dataclasses import dataclass

import numpy as np
import pytest

from featherstar.hil.emulated_bench import CATCH_UP_YIELD_S, LOADCELL_UNIT, SERVO_UNIT, Emulator
from featherstar.hil.link import DeviceURL
from featherstar.hil.plant import FlatPlatePlant
from featherstar.hil.registers import Function, load_loadcell_map, load_servo_map
from featherstar.hil.timed_io import (ClockSync, DeviceClock, LogReader, player_state, start_log,
                                      start_trajectory, upload_trajectory)
from featherstar.hil.timed_registers import PlayerState

STEP_S = 0.004


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class DirectLink:
    """A link that calls the emulator's unit handlers in-process (no sockets, no wall clock)."""

    def __init__(self, emulator: Emulator) -> None:
        self.units = emulator.units()

    def _ask(self, unit: int, fc: int, space: str, address: int, count: int, values=None):
        reply = asyncio.run(self.units[unit][1](fc, space, address, count, values))
        assert not isinstance(reply, int), f"exception {reply}"
        return reply

    def read(self, function: Function, address: int, count: int, unit: int) -> list[int]:
        fc, space = (3, "holding") if function is Function.HOLDING else (4, "input")
        return self._ask(unit, fc, space, address, count)

    def write(self, address: int, values, unit: int) -> None:
        self._ask(unit, 16, "holding", address, len(values), list(values))

    def write_one(self, address: int, value: int, unit: int) -> None:
        self._ask(unit, 6, "holding", address, 1, [value])


@dataclass
class Block:
    map: object
    link: DirectLink
    url: DeviceURL


def _bench(clock: Clock):
    emu = Emulator(load_loadcell_map("loadcell-float32-abcd"), load_servo_map("servo-default"),
                   FlatPlatePlant(), noise_N=0.0, seed=1, clock=clock)
    link = DirectLink(emu)
    servo = Block(emu.servo_map, link, DeviceURL("modbus-tcp", SERVO_UNIT))
    cell = Block(emu.loadcell_map, link, DeviceURL("modbus-tcp", LOADCELL_UNIT))
    link.write_one(emu.servo_map.enable.address, emu.servo_map.enable.value, SERVO_UNIT)
    return emu, servo, cell


def _stroke(n: int) -> list[float]:
    return [0.5 * math.sin(2 * math.pi * k * STEP_S / 1.0) for k in range(n)]


def _play(schedule_s: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """Play a 2 s stroke, the emulator getting the CPU at the given wall-clock steps."""
    clock = Clock()
    emu, servo, cell = _bench(clock)
    upload_trajectory(servo, STEP_S, _stroke(500))
    start_log(cell, STEP_S)
    start_trajectory(servo, clock.t - emu.sessions["servo"].boot_s + 0.1)
    reader = LogReader(cell, emu.loadcell_map.value, DeviceClock(cell))
    for dt in schedule_s:
        clock.t += dt
        while emu.tick_interval_s() == CATCH_UP_YIELD_S:   # the ticker catching up, piece by piece
            emu.tick()
        emu.tick()
    assert player_state(servo) is PlayerState.DONE
    reader.poll()
    return np.asarray(reader.times_s), np.asarray(reader.values)


def test_samples_do_not_depend_on_when_the_emulator_got_the_cpu():
    regular = _play([0.004] * 600)
    rng = random.Random(3)
    starved = []      # 20 ms slices, with stalls of up to 1 s (a loaded machine)
    while sum(starved) < 2.4:
        starved.append(rng.choice([0.02, 0.02, 0.05, 0.3, 1.0]))
    irregular = _play(starved)
    n = min(len(regular[0]), len(irregular[0]))
    assert n > 550
    assert np.array_equal(regular[0][:n], irregular[0][:n])        # the same device times
    peak = np.max(np.abs(regular[1][:n]))
    assert peak > 0.05                                              # a stroke that pushes water
    # Equal but for where the plant's pieces end (a sample interpolates inside one piece):
    # worst at the stroke's abrupt end, 1.2 % of the peak.
    error = np.abs(regular[1][:n] - irregular[1][:n])
    assert np.max(error) < 0.02 * peak and np.sqrt(np.mean(error**2)) < 0.002 * peak


def test_a_ring_that_overran_counts_the_lost_samples_and_keeps_the_newest_in_order():
    clock = Clock()
    emu, _servo, cell = _bench(clock)
    start_log(cell, STEP_S)
    reader = LogReader(cell, emu.loadcell_map.value, DeviceClock(cell))
    capacity = emu.loadcell_map.timed.log.capacity
    for _ in range(int(1.5 * capacity * STEP_S / 0.02)):    # 1.5 rings without a read
        clock.t += 0.02
        emu.tick()
    taken = reader.head()
    lost = reader.poll()
    assert lost == taken - capacity > 0 and len(reader.times_s) == capacity
    assert np.allclose(np.diff(reader.times_s), STEP_S)


@pytest.mark.parametrize("drift_ppm", [0.0, 80.0, -300.0])
def test_the_clock_mapping_undoes_offset_and_drift(drift_ppm):
    clock = DeviceClock.__new__(DeviceClock)
    rate = drift_ppm * 1e-6
    offset0 = 1234.5

    def device(pc_s: float) -> float:
        return pc_s + offset0 + rate * (pc_s - 10.0)
    clock.syncs = [ClockSync(10.0, device(10.0) - 10.0, 1e-4),
                   ClockSync(70.0, device(70.0) - 70.0, 1e-4)]
    for pc_s in (10.0, 33.3, 70.0, 80.0):
        assert clock.to_pc_s(device(pc_s)) == pytest.approx(pc_s, abs=1e-9)
    assert clock.drift_ppm() == pytest.approx(drift_ppm, abs=1e-6)


def test_the_uploaded_stroke_is_the_one_the_overrides_ask_for():
    """`optimize --hardware ...&clock=device` sets the controller's times on every run: the
    stroke played is the overridden one (a scene's dict keeps --set values apart, so the
    stroke block is rebuilt from the scene and the values applied again)."""
    from featherstar.cosim.scenes import load_scene
    from featherstar.hil.hardware import with_hardware
    from featherstar.hil.timed_run import stroke_of

    url = "modbus-tcp://127.0.0.1:1?unit={}&clock=device"
    scene = with_hardware(load_scene("testbed"), {"servo": url.format(2), "loadcell": url.format(1)})
    times = {"controller.t_up_s": 0.1, "controller.t_hold_up_s": 0.2,
             "controller.t_down_s": 0.3, "controller.t_hold_down_s": 0.4}
    _, t_s, angle_rad, period_s = stroke_of(scene, {**times, "master.t_end_s": 2.0})
    assert period_s == pytest.approx(1.0) and t_s[-1] == pytest.approx(2.0)
    _, _, default_rad, default_period_s = stroke_of(scene, {"master.t_end_s": 2.0})
    assert default_period_s == pytest.approx(1.5)
    # 0.1 s up then held: at 0.2 s the overridden stroke is at its top, the default still rising
    k = int(round(0.2 / (t_s[1] - t_s[0])))
    assert angle_rad[k] == pytest.approx(angle_rad.max(), abs=1e-3) and default_rad[k] < 0.9 * default_rad.max()
