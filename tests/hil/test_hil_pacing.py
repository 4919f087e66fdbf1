"""Pacer, recorder and run_paced, including a run whose emulator process is killed."""
from __future__ import annotations

import csv
import json
import math
import time

import pytest

from featherstar.hil.blocks import LoadCell, Servo
from featherstar.hil.emulator import spawn_emulator
from featherstar.hil.errors import DeviceFault
from featherstar.hil.pacing import Pacer, run_paced
from featherstar.hil.recorder import Recorder

# Generous: a loaded 2-core machine can stall the emulator for tens of ms.
T = 1.0


def read_rows(path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_pacer_keeps_the_grid_with_a_light_step():
    pacer = Pacer(0.01, end_s=0.2)
    ticks = []
    while (tick := pacer.wait()) is not None:
        ticks.append(tick)
    # Timing on a shared 2-core machine is not ours to assert (the loop rate is a benchmark):
    # what must hold is the grid itself. Late wake-ups skip ticks but never lose time.
    indices = [t.index for t in ticks]
    assert indices[0] == 0 and indices == sorted(set(indices)) and indices[-1] == 20
    assert all(t.t_s == pytest.approx(0.01 * t.index) for t in ticks)
    assert ticks[0].h_s == 0.0
    assert sum(t.h_s for t in ticks) == pytest.approx(0.2)
    assert all(t.wall_s >= t.t_s for t in ticks)


class SimulatedClock:
    """A monotonic clock that only moves when slept on or told to (no wall clock, no load)."""

    def __init__(self) -> None:
        self.now_s = 100.0

    def __call__(self) -> float:
        return self.now_s

    def sleep(self, dt_s: float) -> None:
        self.now_s += dt_s


def _paced(end_s: float, busy_s) -> tuple[Pacer, list]:
    clock = SimulatedClock()
    pacer = Pacer(0.01, end_s=end_s, clock=clock, sleep=clock.sleep)
    ticks = []
    while (tick := pacer.wait()) is not None:
        ticks.append(tick)
        clock.sleep(busy_s(tick.index))      # the step's work
    return pacer, ticks


def test_pacer_records_deadline_misses_and_skips_passed_ticks():
    # 3.5 periods of work at ticks 5 and 15: ticks 6-7 (16-17) pass unrun, 8 (18) starts late
    pacer, ticks = _paced(0.3, lambda k: 0.035 if k in (5, 15) else 0.001)
    stats = pacer.stats
    assert stats.n_misses == 2 and stats.n_skipped == 4
    late = [t for t in ticks if t.skipped]
    assert [t.index for t in late] == [8, 18] and all(t.skipped == 2 for t in late)
    assert late[0].h_s == pytest.approx(0.03) and late[0].late_s == pytest.approx(0.005)
    assert sum(t.h_s for t in ticks) == pytest.approx(ticks[-1].t_s)   # no time lost
    assert stats.summary()["busy_max_s"] == pytest.approx(0.035)


def test_a_step_that_overruns_the_end_still_gets_the_last_tick():
    pacer, ticks = _paced(0.1, lambda k: 0.03 if k == 8 else 0.001)   # ends past 0.1 s
    assert ticks[-1].index == 10 and ticks[-1].t_s == pytest.approx(0.1)
    assert ticks[-1].skipped == 1 and ticks[-1].late_s == pytest.approx(0.01)
    assert sum(t.h_s for t in ticks) == pytest.approx(0.1)


def test_recorder_flushes_periodically_so_a_crash_keeps_the_data(tmp_path):
    rec = Recorder(tmp_path, flush_s=0.05)
    rec.write({"t_s": 0.0, "thrust_N": 0.1})
    time.sleep(0.06)
    rec.write({"t_s": 0.01, "thrust_N": 0.2})
    # Not closed: what another process (or a post-mortem) sees on disk.
    rows = read_rows(tmp_path / "samples.csv")
    assert [r["thrust_N"] for r in rows] == ["0.1", "0.2"]
    with pytest.raises(ValueError, match="first sample did not have"):
        rec.write({"t_s": 0.02, "extra": 1.0})
    rec.close()


def test_run_paced_records_samples_and_stats(tmp_path):
    def step(t_s: float, h_s: float) -> dict[str, float]:
        return {"x": math.sin(t_s)}
    result = run_paced(step, 200.0, 0.25, tmp_path / "run", meta={"scene": "test"})
    rows = read_rows(result.samples_csv)
    assert result.n_samples == len(rows) <= 51
    assert list(rows[0]) == ["t_s", "wall_s", "late_s", "step_s", "x"]
    assert float(rows[-1]["t_s"]) == pytest.approx(0.25)
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["meta"] == {"scene": "test"} and run["stats"]["n_ticks"] == result.n_samples
    assert not (tmp_path / "run" / "fault.json").exists()


def test_run_paced_records_a_slow_step_as_deadline_misses(tmp_path):
    def step(t_s: float, h_s: float) -> dict[str, float]:
        if 0.05 <= t_s < 0.1:
            time.sleep(0.015)
        return {"h_s": h_s}
    result = run_paced(step, 100.0, 0.2, tmp_path)
    assert result.stats["n_misses"] >= 3
    assert max(float(r["h_s"]) for r in read_rows(result.samples_csv)) >= 0.02 - 1e-9


@pytest.mark.hil
def test_killing_the_emulator_mid_run_leaves_data_and_a_fault_note(tmp_path):
    emu = spawn_emulator(seed=4)
    cell = LoadCell("thrust-cell", emu.loadcell_url, timeout_s=T)
    servo = Servo("servo", emu.servo_url, timeout_s=T, safe_timeout_s=0.5)  # the device is dead
    try:
        cell.start(0.0)
        servo.start(0.0)

        def step(t_s: float, h_s: float) -> dict[str, float]:
            if h_s > 0:
                servo.do_step(t_s - h_s, h_s)
                cell.do_step(t_s - h_s, h_s)
            servo.set_inputs({"setpoint_rad": 0.5 * math.sin(2 * math.pi * t_s)})
            sample = {**servo.get_outputs(), **cell.get_outputs()}
            if t_s >= 0.6 and emu.proc.poll() is None:
                emu.kill()       # at run time 0.6 s, however late the loaded PC got there
            return sample

        with pytest.raises(DeviceFault) as info:
            run_paced(step, 100.0, 10.0, tmp_path, flush_s=0.1)
        assert info.value.device in ("servo", "thrust-cell")
        rows = read_rows(tmp_path / "samples.csv")
        # every tick run up to the kill (a late one skips ticks), and none after it
        assert float(rows[-1]["t_s"]) >= 0.6 - 1e-9 and float(rows[-2]["t_s"]) < 0.6
        assert 10 <= len(rows) <= 61
        assert float(rows[-1]["t_s"]) < info.value.t_s
        fault = json.loads((tmp_path / "fault.json").read_text())
        assert fault["device"] == info.value.device and fault["samples_written"] == len(rows)
        assert fault["fault"] in ("link_lost", "connect", "timeout")
        assert fault["t_s"] == pytest.approx(info.value.t_s)
        assert json.loads((tmp_path / "run.json").read_text())["fault"] == "fault.json"
    finally:
        servo.close()           # the link is down: must not raise
        cell.close()
        emu.stop()
