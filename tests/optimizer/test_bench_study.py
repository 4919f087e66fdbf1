"""The optimizer on the bench: studies against the Modbus emulator (a child process) on loopback.

Short on purpose: strokes of 1 s, one measured period, no settling, 0.1 s rest; the flat-plate
plant starts at once and needs no FMU.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading

import numpy as np
import pytest
from featherstar.hil.emulator import spawn_emulator
from featherstar.optimizer.bayes import optimize
from featherstar.optimizer.bench.objective import BenchObjective, DiscardedRun, Retrying, discard_reasons
from featherstar.optimizer.bench.run import BenchFault, BenchRun
from featherstar.optimizer.bench.sim_prior import SimPrior
from featherstar.optimizer.bench.study import run_bench_study
from featherstar.optimizer.cli import main as optimizer_main
from featherstar.optimizer.evaluation import MeasurementPlan
from featherstar.optimizer.loadcell import LoadCell
from featherstar.optimizer.objective import SceneObjective
from featherstar.optimizer.space import stroke_space

pytestmark = pytest.mark.hil

PERIOD_S = 1.0
SPACE = stroke_space(PERIOD_S)
PLAN = MeasurementPlan(load_cell=LoadCell(noise_sd_N=0.0, sample_rate_hz=250.0), settle_periods=0, periods=1, seed=3)
ITERATIONS = 4
# Fail fast when the device is gone; recover from a brief stall (which then discards the run).
OPTIONS = "&timeout_s=0.1&reconnect_s=2&start_retry_s=0.5"
SERVO_OPTIONS = OPTIONS + "&safe_timeout_s=0.3"
# The study's logic (faults, resume, priors) on devices that keep the time, so a busy PC cannot
# discard its runs; the streamed stall test is the one about the PC's timing.
DEVICE_TIMED = "&clock=device"


def _bench(emulator, clock: str = DEVICE_TIMED) -> BenchObjective:
    return BenchObjective("testbed", {"servo": emulator.servo_url + SERVO_OPTIONS + clock,
                                      "loadcell": emulator.loadcell_url + OPTIONS + clock},
                          {"feather.morphology": "plain"}, settle_periods=PLAN.settle_periods, rest_s=0.1)


def _study(emulator, out, clock: str = DEVICE_TIMED, **kwargs):
    return run_bench_study(_bench(emulator, clock), SPACE, out, plan=PLAN, iterations=ITERATIONS,
                           validation_repeats=2, validation_periods=1, label="plate", **kwargs)


def _skip_unless_streaming_keeps_time(emulator) -> None:
    """The stall must be the only reason to discard a run: skip, with the measured reasons, when
    two unstalled streamed runs on this machine are discarded right now (a busy PC)."""
    reasons = []
    for _ in range(2):
        try:
            _bench(emulator, clock="")({}, 1.5)     # the scene's own stroke, one period
            return
        except DiscardedRun as discarded:
            reasons = discarded.reasons
    pytest.skip(f"the machine cannot stream a bench run in time now: {'; '.join(reasons)}")


def _records(out):
    return [json.loads(line) for line in (out / "evaluations.jsonl").read_text().splitlines()]


@pytest.mark.realtime
def test_a_stalled_streamed_run_is_discarded_and_repeated_and_the_study_completes(tmp_path, keeps_time,
                                                                                   skip_if_time_was_lost):
    emulator = spawn_emulator(plant="flat-plate", noise_N=0.002, seed=1)
    stalled = []

    def stall_the_next_run(record):
        # Freeze the device 0.5 s into the run after the second evaluation, for 0.4 s.
        if record["kind"] == "evaluation" and record["index"] == 1 and not stalled:
            stalled.append(True)
            threading.Timer(0.6, os.kill, (emulator.proc.pid, signal.SIGSTOP)).start()
            threading.Timer(1.0, os.kill, (emulator.proc.pid, signal.SIGCONT)).start()

    try:
        _skip_unless_streaming_keeps_time(emulator)
        summary = _study(emulator, tmp_path, clock="", on_record=stall_the_next_run)
    finally:
        emulator.stop()
    records = _records(tmp_path)
    assert [r["index"] for r in records if r["kind"] == "evaluation"] == list(range(ITERATIONS))
    discarded = [r for r in records if r["kind"] == "discarded"]
    stalled_runs = [r for r in discarded if r.get("index") == 2]
    assert stalled_runs, discarded
    assert any("gap" in reason or "late" in reason for reason in stalled_runs[0]["reasons"])
    assert summary["measured"] is True and summary["discarded_runs"] == len(discarded)
    assert summary["iterations"] == ITERATIONS
    assert {r["controller"] for r in records if r["kind"] == "validation"} == {"best", "baseline"}
    # Besides the stall, runs discarded for time lost to the machine's load: the ranking below then
    # rests on runs kept with a few late steps, and says nothing about the study.
    skip_if_time_was_lost(reasons=[reason for r in discarded if r is not stalled_runs[0] for reason in r["reasons"]])
    # A slow upstroke with a fast downstroke beats the symmetric stroke on a drag plate.
    assert summary["thrust_ratio"] > summary["baseline_thrust_ratio"] - 0.05, summary
    assert (tmp_path / "fig6_progress.png").stat().st_size > 0 and (tmp_path / "fig8_validation.png").exists()


def test_a_killed_device_pauses_the_study_and_resume_logs_every_evaluation_once(tmp_path):
    emulator = spawn_emulator(plant="flat-plate", noise_N=0.002, seed=1)
    port = emulator.port

    def kill_during_the_third(record):
        if record["kind"] == "evaluation" and record["index"] == 1:
            threading.Timer(0.5, emulator.kill).start()   # 0.1 s rest, then mid-run

    try:
        with pytest.raises(BenchFault, match="study paused.*--resume"):
            _study(emulator, tmp_path, on_record=kill_during_the_third)
    finally:
        emulator.stop()
    paused = _records(tmp_path)
    assert [r["index"] for r in paused if r["kind"] == "evaluation"] == [0, 1]
    fault = next(r for r in paused if r["kind"] == "fault")
    assert fault["index"] == 2

    emulator = spawn_emulator(port=port, plant="flat-plate", noise_N=0.002, seed=2)
    try:
        summary = _study(emulator, tmp_path, resume=True)
    finally:
        emulator.stop()
    records = _records(tmp_path)
    assert records[: len(paused)] == paused   # nothing lost or rewritten
    evaluations = [r for r in records if r["kind"] == "evaluation"]
    assert [r["index"] for r in evaluations] == list(range(ITERATIONS))
    assert evaluations[2]["params"] == fault["params"]   # the interrupted point, asked again
    assert summary["faults"] == 1 and summary["iterations"] == ITERATIONS


def test_cli_study_on_the_bench_with_a_simulated_prior_writes_measured_outputs(tmp_path):
    # The prior: a short simulated study of the same feather and stroke period.
    optimize(SceneObjective("testbed", {"feather.morphology": "plain"}), SPACE, tmp_path / "sim" / "evaluations.jsonl",
             iterations=5, plan=MeasurementPlan(settle_periods=0, periods=1, seed=5),
             context={"scene": "testbed", "overrides": {"feather.morphology": "plain"}})
    prior = SimPrior.load(tmp_path / "sim", feather={"morphology": "plain"}, space=SPACE, maximize=True)
    out = tmp_path / "bench"
    emulator = spawn_emulator(plant="flat-plate", noise_N=0.002, seed=1)
    try:
        done = subprocess.run(
            [sys.executable, "-m", "featherstar", "optimize", "testbed", "--set", "feather.morphology=plain",
             "--hardware", f"servo={emulator.servo_url}{SERVO_OPTIONS}{DEVICE_TIMED}",
             "--hardware", f"loadcell={emulator.loadcell_url}{OPTIONS}{DEVICE_TIMED}",
             "--iterations", "4", "--period", "1", "--settle-periods", "0", "--periods", "1", "--rest-s", "0.1",
             "--validation-repeats", "2", "--validation-periods", "1", "--out", str(out), "--prior", str(tmp_path / "sim")],
            capture_output=True, text=True, timeout=120)
    finally:
        emulator.stop()
    assert done.returncode == 0, done.stderr
    assert "ON THE BENCH" in done.stdout and "validated best" in done.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["measured"] is True and summary["iterations"] == 4
    assert summary["measurement"]["noise_sd_N"] == 0.0
    assert summary["prior"]["evaluations"] == 5
    # The initial design is the simulated study's best strokes, best first.
    evaluations = [r for r in _records(out) if r["kind"] == "evaluation"]
    assert [r["params"] for r in evaluations] == prior.initial_points(SPACE, 4, maximize=True)
    assert all(r["from_prior"] for r in evaluations)


@pytest.mark.parametrize("args, message", [
    (["--prior", "somewhere"], "--prior applies to a study on the bench"),
    (["--hardware", "servo=modbus-tcp://127.0.0.1:1?unit=2"], "--hardware loadcell=URL is missing"),
    (["--hardware", "servo=modbus-tcp://127.0.0.1:1?unit=2", "--hardware", "loadcell=modbus-tcp://127.0.0.1:1?unit=1",
      "--batch-size", "2"], "one bench runs one stroke at a time"),
    (["--hardware", "servo=modbus-tcp://127.0.0.1:1?unit=2&timeout_s=-1",
      "--hardware", "loadcell=modbus-tcp://127.0.0.1:1?unit=1"], "timeout_s='-1' must be a positive number"),
    (["--hardware", "servo=modbus-tcp://127.0.0.1:1?unit=2", "--hardware", "loadcell=modbus-tcp://127.0.0.1:1?unit=1"],
     "scene 'kinematic' has no simulated 'servo' block to replace"),
])
def test_bad_bench_options_are_refused_in_one_line(tmp_path, capsys, args, message):
    scene = "kinematic" if message.startswith("scene") else "testbed"
    assert optimizer_main(["optimize", scene, "--out", str(tmp_path / "out"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def _run(thrust, **summary):
    t = np.linspace(0.0, 2.0, 501)
    base = {"worst_lateness_s": 0.0, "deadline_misses": 0, "gaps": 0, "reconnects": 0, "stats": {"macro_steps": 500},
            "validity": {"invalid_periods": []}, "window_s": [1.0, 2.0]}
    return BenchRun(t, thrust(t), np.zeros_like(t), {**base, **summary}, True)


@pytest.mark.parametrize("summary, thrust, reason", [
    ({}, lambda t: np.sin(2 * np.pi * t), None),
    ({"worst_lateness_s": 0.06}, lambda t: np.sin(2 * np.pi * t), "0.060 s late (limit 0.05 s)"),
    ({"deadline_misses": 51}, lambda t: np.sin(2 * np.pi * t), "51 of 500 steps missed their deadline"),
    ({"deadline_misses": 50}, lambda t: np.sin(2 * np.pi * t), None),   # 10 % exactly: jitter, kept
    ({"gaps": 1}, lambda t: np.sin(2 * np.pi * t), "1 data gap"),
    ({"reconnects": 1}, lambda t: np.sin(2 * np.pi * t), "1 device reconnect"),
    ({"validity": {"invalid_periods": [{"reasons": ["loadcell: data gap at t=1.2 s"]}]}}, lambda t: np.sin(2 * np.pi * t),
     "1 measured period(s) excluded: loadcell: data gap"),
    ({}, lambda t: 1.0 + np.sin(2 * np.pi * t) ** 2, "no negative thrust in the measured window"),
])
def test_which_runs_are_discarded(summary, thrust, reason):
    reasons = discard_reasons(_run(thrust, **summary))
    assert (reasons == []) if reason is None else any(reason in r for r in reasons), reasons


# 4 ms samples: a record may end one sample short (a device's own sampling grid), not 11 ms short.
@pytest.mark.parametrize("last_read_s, discarded", [(1.989, True), (1.997, False), (2.0, False), (2.004, False)])
def test_a_record_that_ends_short_of_the_run_is_a_discarded_run_not_a_dead_study(monkeypatch, last_read_s, discarded):
    # A streamed run stamps samples with the PC's read times: under load one ended 11 ms short of the
    # run, and the metrics' whole-period check then stopped the study with an OptimizerError.
    time_s = np.linspace(0.0, last_read_s, 501)
    run = BenchRun(time_s, np.sin(2 * np.pi * time_s), np.zeros_like(time_s), _run(lambda t: np.sin(2 * np.pi * t)).summary, True)
    monkeypatch.setattr("featherstar.optimizer.bench.objective.run_on_bench", lambda *args: run)
    bench = BenchObjective("testbed", {}, rest_s=0.0)
    seen = []
    retrying = Retrying(bench, lambda reasons, summary: seen.append(reasons), max_attempts=2)
    if discarded:
        with pytest.raises(BenchFault, match="runs in a row were discarded"):
            retrying({}, 2.0)
        assert len(seen) == 2 and "the samples span 1.989 s of the 2.000 s run" in seen[0][0]
    else:
        assert len(retrying({}, 2.0).time_s) == 501 and seen == []


def test_the_rest_counts_from_the_previous_run_s_end_whatever_the_optimizer_computed(monkeypatch):
    # The tare is taken at the rest's end; a rest added to the optimizer's time between runs
    # made a run's tare, and so its TR, depend on how long the optimizer computed.
    now = [100.0]
    slept = []
    time_s = np.linspace(0.0, 2.0, 501)
    run = BenchRun(time_s, np.sin(2 * np.pi * time_s), np.zeros_like(time_s),
                   _run(lambda t: np.sin(2 * np.pi * t)).summary, True)

    def bench_run(*args):
        now[0] += 2.0   # the run itself
        return run

    def sleep(s):
        slept.append(s)
        now[0] += s

    monkeypatch.setattr("featherstar.optimizer.bench.objective.run_on_bench", bench_run)
    monkeypatch.setattr("featherstar.optimizer.bench.objective.time.monotonic", lambda: now[0])
    monkeypatch.setattr("featherstar.optimizer.bench.objective.time.sleep", sleep)
    bench = BenchObjective("testbed", {}, rest_s=5.0)
    for computed_s in (0.0, 1.5, 4.0, 7.0):   # the optimizer's time before each run
        now[0] += computed_s
        bench({}, 2.0)
    assert slept == [5.0, 3.5, 1.0, 0.0]   # first: the whole rest; then rest_s since the run's end
