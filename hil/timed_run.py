"""Device-timed hardware runs: the devices keep the time, the PC uploads, starts and reads.

Streaming a setpoint every 4 ms from Python and reading the load cell on the same beat ends
INCOMPLETE on a loaded PC (deadline misses). With `clock=device` on both --hardware URLs the
PC instead
  1. computes the stroke (the scene's open-loop stroke block, simulated alone, then clamped and
     rate-limited as the streaming servo block does, after a first sample where the servo is:
     `trajectory_samples`) and uploads it to the servo;
  2. starts both devices' sample logs, synchronises each device's clock with its own
     (shortest of several round trips), and arms the trajectory at a device-clock start time;
  3. polls in blocks (every POLL_S, whatever the load): the time-stamped samples of the load
     cell and of the servo's read-back, the boot ids (a restart), the player's state, and
     re-arms the servo's watchdog;
  4. synchronises the clocks again (drift), maps every sample to run time through its own
     device's clock, and measures TR and mean thrust on those time stamps.
Samples overwritten before they were read (the ring overran) are a `gap` event in their
period; a restart ends the trusted data as in streaming (featherstar.cosim.swimmer.validity).
A stop (signal, fault) commands the servo's safe position like any hardware run.
"""
from __future__ import annotations

import logging
import math
import time
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ..cosim.coupling.pacing import STOP
from ..cosim.errors import RunInterrupted, SceneError, StepError
from ..cosim.scene.data import Scene, scene_from_dict
from ..cosim.swimmer.metrics import scene_metrics
from ..cosim.swimmer.run import RunResult, run_scene
from ..cosim.swimmer.validity import apply_validity
from .blocks import LoadCell, Servo
from .device import ReadPlan
from .errors import DeviceFault
from .hardware import LOADCELL_BLOCK
from .link import FaultSignal
from .session import SessionWatch
from .timed_io import (DeviceClock, LogReader, player_state, start_log, start_trajectory,
                       upload_trajectory)
from .timed_registers import PlayerState

log = logging.getLogger(__name__)
POLL_S = 0.05             # the PC reads blocks this often; the rings hold seconds
# No request has a deadline (the samples wait in the ring): a slow reply is waited for, a
# failed poll retried this long, a timeout re-dialled (the boot id shows a restart).
REQUEST_TIMEOUT_S = 1.0
RETRY_S = 3.0
LEAD_S = 0.3              # the trajectory starts this long after it is armed
# The watchdog's timeout while the device plays: a poll of a loaded PC may take long, and a
# stroke that plays on for 2 s after the PC died ends anyway (then the watchdog holds it safe).
TIMED_WATCHDOG_MS = 2000
LOG_STALL_S = 10.0         # a log that gives no new sample for this long has stopped
# The safe position after the run is retried this long unless the URL says safe_timeout_s:
# no request has a deadline in this mode, and an emulator that fell behind a loaded PC took
# more than the streaming default of 5 s to answer (the 10th run of a loaded bench study
# paused on it). Meanwhile the device's watchdog holds the servo.
TIMED_SAFE_TIMEOUT_S = 30.0
THRUST, ANGLE, COMMAND = f"{LOADCELL_BLOCK}.thrust_N", "servo.angle_rad", "controller.angle_rad"


def is_device_timed(scene: Scene) -> bool:
    return scene.to_dict()["blocks"].get("servo", {}).get("parameters", {}).get("clock") == "device"


def run_bench_scene(scene: Scene, overrides: Mapping[str, Any] | None = None, *,
                    outputs: Sequence[str] | None = None, progress: bool = False,
                    strict_window: bool = False) -> RunResult:
    """A hardware scene's run: device-timed when its URLs asked for it, else streamed."""
    if not is_device_timed(scene):
        return run_scene(scene, overrides, outputs=outputs, progress=progress,
                         strict_window=strict_window)
    return run_device_timed(scene, overrides, outputs=outputs)


def stroke_of(scene: Scene, overrides: Mapping[str, Any]) -> tuple[str, np.ndarray, np.ndarray, float]:
    """(source signal, times, angles, period) of the open-loop block that drives the servo."""
    sc = scene.with_overrides(overrides)
    data = sc.to_dict()
    sources = [c.split("->")[0].strip() for c in data["connections"]
               if c.replace(" ", "").endswith("->servo.setpoint_rad")]
    if len(sources) != 1:
        raise SceneError("clock=device: the servo's setpoint must come from one block")
    source = sources[0]
    block = source.split(".")[0]
    if any(c.replace(" ", "").split("->")[1].startswith(f"{block}.") for c in data["connections"]):
        raise SceneError(f"clock=device: block '{block}' drives the servo and takes inputs (a "
                         "simulated block inside the loop); such scenes need the streaming mode")
    step_s = float(data["master"]["step_s"])
    # The block as the scene file gives it, its --set values applied again below: a scene's
    # dict keeps them apart ("overrides"), and a scene is not read back from that form.
    stroke = dict(data, blocks={block: scene.to_dict()["blocks"][block]}, connections=[],
                  metrics={"thrust": source, "settle_periods": 0}, aliases={})
    stroke["master"] = dict(data["master"], coupling="jacobi", realtime=False, step_s=step_s,
                            output_interval_s=step_s, adaptive=False)
    mine = {k: v for k, v in overrides.items()
            if block in (scene.aliases.get(str(k).partition(".")[0], ()) or (str(k).partition(".")[0],))}
    stroke_scene = scene_from_dict(stroke, name=f"{sc.name}-stroke").with_overrides(
        {f"{block}.{str(k).partition('.')[2]}": v for k, v in mine.items()})
    result = run_scene(stroke_scene, outputs=[source])
    return source, np.asarray(result.time), np.asarray(result[source]), result.summary["period_s"]


def trajectory_samples(present_rad: float, target_rad: Sequence[float], rate_limit_rad_s: float, step_s: float,
                       clamp: Callable[[float], float]) -> list[float]:
    """The servo's uploaded trajectory for targets sampled at t_k = k·step_s (k = 0..N).

    Sample k is played from t_k: sample 0 is where the servo is (the player also holds it from
    arming, 0.3 s ahead: anything else moved the servo before time zero; a stroke starting away
    from rest was pre-positioned by one rate-limited step and the feather was moving at t = 0),
    sample k >= 1 the target at t_k, clamped and rate-limited from the sample before. These are
    a streamed run's setpoints on its record's time axis: under the hardware scene's Gauss-Seidel
    coupling the streaming servo block writes the stroke at a step's end at the step's start, and
    the master stamps what it reads then at the step's end; device samples carry their own time."""
    samples = [float(present_rad)]
    limit_rad = rate_limit_rad_s * step_s
    for x in list(target_rad)[1:]:
        samples.append(min(max(clamp(float(x)), samples[-1] - limit_rad), samples[-1] + limit_rad))
    return samples


def _blocks(sc: Scene) -> tuple[Servo, LoadCell]:
    blocks = sc.to_dict()["blocks"]
    sv = {k: v for k, v in blocks["servo"]["parameters"].items() if k != "clock"}
    sv.setdefault("safe_timeout_s", TIMED_SAFE_TIMEOUT_S)
    lc = {k: v for k, v in blocks[LOADCELL_BLOCK]["parameters"].items() if k != "clock"}
    servo, cell = Servo("servo", **sv), LoadCell(LOADCELL_BLOCK, **lc)
    for b, needs in ((servo, ("clock", "trajectory", "log")), (cell, ("clock", "log"))):
        missing = [t for t in needs if getattr(b.map.timed, t) is None]
        if missing:
            raise SceneError(f"clock=device: register map {b.map.source} of {b.name} has no "
                             f"[{'], ['.join(missing)}] table(s); use the streaming mode")
    return servo, cell


def run_device_timed(scene: Scene, overrides: Mapping[str, Any] | None = None, *,
                     outputs: Sequence[str] | None = None) -> RunResult:
    """Run a hardware scene with device-timed devices; raises SceneError before any I/O,
    StepError (with `.partial`) when a device fails or the run is stopped."""
    wall0 = time.perf_counter()
    sc = scene.with_overrides(overrides or {})
    allowed = {THRUST, ANGLE, COMMAND}
    if outputs and set(outputs) - allowed:
        raise SceneError(f"clock=device records {', '.join(sorted(allowed))}; not "
                         f"{', '.join(sorted(set(outputs) - allowed))}")
    _source, t_cmd, target_rad, period_s = stroke_of(scene, overrides or {})
    servo, cell = _blocks(sc)
    step_s = float(t_cmd[1] - t_cmd[0])
    t_end_s = float(t_cmd[-1])
    if len(t_cmd) > servo.map.timed.trajectory.capacity:
        raise SceneError(f"clock=device: {len(t_cmd)} trajectory samples exceed the servo's "
                         f"capacity {servo.map.timed.trajectory.capacity}; shorten the run")
    run = _TimedRun(servo, cell, step_s, t_end_s)
    error: StepError | None = None
    try:
        run.execute(target_rad)
    except DeviceFault as exc:
        error = StepError(exc.device, run.t_s, str(exc), cause="a device failed")
    except KeyboardInterrupt as exc:
        cause = exc.signal_name if isinstance(exc, RunInterrupted) else "SIGINT"
        error = StepError("master", run.t_s, f"interrupted by {cause}",
                          cause="the run was stopped from outside")
        error.interrupted = cause
    except FaultSignal as exc:
        error = StepError("master", run.t_s, f"{exc.fault.value}: {exc.detail}",
                          cause="a device failed")
    finally:
        servo.close()
        cell.close()
    result = run.result(sc, period_s, t_cmd, run.commands_rad, time.perf_counter() - wall0,
                        error, overrides)
    if error is not None:
        error.partial = result
        raise error
    return result


class _TimedRun:
    """The devices' side of one device-timed run and what it read."""

    def __init__(self, servo: Servo, cell: LoadCell, step_s: float, t_end_s: float) -> None:
        self.servo, self.cell, self.step_s, self.t_end_s = servo, cell, step_s, t_end_s
        self.clocks = {"servo": DeviceClock(servo), "loadcell": DeviceClock(cell)}
        self.logs = {"servo": LogReader(servo, servo.map.position, self.clocks["servo"]),
                     "loadcell": LogReader(cell, cell.map.value, self.clocks["loadcell"])}
        self.sessions = {name: SessionWatch(b.map.session) for name, b in
                         (("servo", servo), ("loadcell", cell)) if b.map.session is not None}
        self.events: list[dict[str, Any]] = []
        self.commands_rad = np.zeros(0)
        self.t_start_pc: float | None = None
        self.t_s = 0.0
        self.polls = 0

    def _guarded(self, name: str, operation):
        deadline = time.monotonic() + RETRY_S
        while True:
            try:
                return operation()
            except FaultSignal as signal:
                if signal.fault.value not in ("timeout", "link_lost", "connect") \
                        or time.monotonic() > deadline:
                    raise DeviceFault(name, signal.fault, self.t_s, signal.detail) from None
                log.warning("%s: %s (%s); retrying", name, signal.fault.value, signal.detail)
                STOP.raise_if_requested()
                time.sleep(0.02)

    def execute(self, target_rad: np.ndarray) -> None:
        servo, cell = self.servo, self.cell
        cell.start(0.0)              # connect and tare, the feather at rest
        servo.start(0.0)             # connect, enable, arm the watchdog, read where it is
        for block in (servo, cell):  # the link is shared: set once, for both
            block.link.set_timeout(max(block.link.timeout_s, REQUEST_TIMEOUT_S))
        samples = trajectory_samples(servo.command_rad, target_rad, servo.rate_limit_rad_s, self.step_s,
                                     servo.clamp)
        self.commands_rad = np.asarray(samples)   # sample k is in force from t_cmd[k]
        self._guarded("servo", lambda: upload_trajectory(servo, self.step_s, samples))
        self._guarded("servo", lambda: start_log(servo, self.step_s))
        self._guarded(LOADCELL_BLOCK, lambda: start_log(cell, self.step_s))
        sv_sync = self._guarded("servo", self.clocks["servo"].sync)
        self._guarded(LOADCELL_BLOCK, self.clocks["loadcell"].sync)
        self.t_start_pc = time.monotonic() + LEAD_S
        self._guarded("servo", lambda: start_trajectory(servo, self.t_start_pc + sv_sync.offset_s))
        last_news = time.monotonic()
        while True:
            STOP.raise_if_requested()
            time.sleep(POLL_S)
            self.t_s = time.monotonic() - self.t_start_pc
            n_before = len(self.logs["loadcell"].times_s)
            done = self._poll()
            if len(self.logs["loadcell"].times_s) > n_before:
                last_news = time.monotonic()
            elif time.monotonic() - last_news > LOG_STALL_S:
                raise DeviceFault(LOADCELL_BLOCK, "stale", self.t_s,
                                  f"no new sample for {LOG_STALL_S} s (its log stopped)")
            if done and min(self._last_sample_s(n) for n in self.logs) > self.t_end_s + self.step_s:
                break
        self._guarded("servo", self.clocks["servo"].sync)
        self._guarded(LOADCELL_BLOCK, self.clocks["loadcell"].sync)
        self._guarded("servo", lambda: start_log(servo, 0.0))      # period 0: logs off
        self._guarded(LOADCELL_BLOCK, lambda: start_log(cell, 0.0))

    def _last_sample_s(self, name: str) -> float:
        """Run time of the newest sample read from a device (the first clock sync)."""
        times, clock = self.logs[name].times_s, self.clocks[name]
        return -math.inf if not times else times[-1] - clock.syncs[0].offset_s - self.t_start_pc

    def _poll(self) -> bool:
        """One block read of both devices; True once the servo has played the whole stroke."""
        self.polls += 1
        wd = self.servo.map.watchdog
        if wd is not None:   # a live client re-arms the device's watchdog (it feeds on writes)
            timeout_ms = max(wd.timeout_ms, TIMED_WATCHDOG_MS)
            self._guarded("servo", lambda: self.servo.link.write_one(
                wd.address, timeout_ms, self.servo.url.unit))
        for name, block in (("servo", self.servo), ("loadcell", self.cell)):
            device = LOADCELL_BLOCK if name == "loadcell" else name
            self._check_session(name, block)
            lost = self._guarded(device, self.logs[name].poll)
            if lost:
                self.events.append({"t_s": self.t_s, "kind": "gap", "device": device,
                                    "detail": f"{lost} samples overwritten before they were read"})
        state = self._guarded("servo", lambda: player_state(self.servo))
        if state is PlayerState.IDLE and self.t_s > 0:
            # A restart between the session reads above and this one also stops the player:
            # read both sessions again so the fault names the cause (a gateway restarts both
            # devices; a loaded PC may have read the load cell's session just before).
            self._check_session("servo", self.servo)
            self._check_session("loadcell", self.cell)
            restarted = any(e["kind"] == "restart" and e["device"] == "servo"
                            for e in self.events)
            raise DeviceFault("servo", "device_error", self.t_s,
                              "the servo restarted: its trajectory is gone" if restarted
                              else "the trajectory player stopped (its watchdog?)")
        return state is PlayerState.DONE

    def _check_session(self, name: str, block: Any) -> None:
        """Read a device's session registers; a new boot id or a reset uptime is an event."""
        watch = self.sessions.get(name)
        if watch is None:
            return
        device = LOADCELL_BLOCK if name == "loadcell" else name
        plan = ReadPlan.build(block.map.read_function, block.map.session.spans())
        regs = self._guarded(device, lambda: plan.read(block.link, block.url.unit))
        restart = self._guarded(device, lambda: watch.check(regs, time.monotonic()))
        if restart:
            self.events.append({"t_s": self.t_s, "kind": "restart", "device": device,
                                "detail": restart, "tare_unknown": name == "loadcell"})

    def _run_times(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        reader, clock = self.logs[name], self.clocks[name]
        if not reader.times_s or self.t_start_pc is None:
            return np.zeros(0), np.zeros(0)
        t = np.array([clock.to_pc_s(x) for x in reader.times_s]) - self.t_start_pc
        return t, np.asarray(reader.values)

    def result(self, sc: Scene, period_s: float, t_cmd: np.ndarray, commands: np.ndarray,
               wall_s: float, error: StepError | None, overrides: Any) -> RunResult:
        t_lc, thrust = self._run_times("loadcell")
        t_sv, angle = self._run_times("servo")
        # Samples from the start to one past the end, so the last period is whole.
        keep = (t_lc >= -self.step_s) & (t_lc <= self.t_end_s + self.step_s)
        t, thrust = t_lc[keep], thrust[keep]
        signals = {THRUST: thrust,
                   ANGLE: np.interp(t, t_sv, angle) if len(t_sv) else np.full(len(t), math.nan),
                   COMMAND: np.interp(t, t_cmd, commands) if len(commands) else np.full(len(t), math.nan)}
        summary: dict[str, Any] = {"scene": sc.name, "coupling": "device-timed",
                                   "wall_time_s": wall_s, "t_end_s": self.t_end_s,
                                   "period_s": period_s, "step_s": self.step_s}
        if error is not None:
            summary.update(error=str(error), failed_block=error.block, failed_at_s=error.t_s)
        finished = error is None and len(t) > 1
        if finished:
            summary.update(scene_metrics(sc.metrics, period_s, t, signals))
        summary.update(self._timing_summary(len(t)))
        summary["safe_position_confirmed"] = {"servo": bool(self.servo.safe_confirmed)}
        complete = False
        if finished:
            complete = apply_validity(summary, t, thrust, period_s, self.step_s, [], self.events)
            if not complete:
                summary["incomplete_reason"] = summary["validity"]["reason"]
        units = {THRUST: "N", ANGLE: "rad", COMMAND: "rad"}
        info = {"notes": [], "overrides": {k: str(v) for k, v in (overrides or {}).items()},
                "scene_fingerprint": sc.fingerprint(), "stats": {"polls": self.polls}}
        return RunResult(sc, t, signals, units, summary, info, complete=complete)

    def _timing_summary(self, n: int) -> dict[str, Any]:
        events = sorted(self.events + self.servo.events + self.cell.events,
                        key=lambda e: float(e.get("t_s", 0.0)))
        clocks = {name: {"offset_s": c.syncs[-1].offset_s if c.syncs else None,
                         "sync_rtt_s": max((s.rtt_s for s in c.syncs), default=None),
                         "drift_ppm": c.drift_ppm() if len(c.syncs) > 1 else None}
                  for name, c in self.clocks.items()}
        return {"deadline_misses": 0, "worst_lateness_s": 0.0,
                "gaps": sum(e["kind"] == "gap" for e in events),
                "reconnects": sum(e["kind"] == "reconnect" for e in events),
                "restarts": sum(e["kind"] == "restart" for e in events), "lags": 0,
                "hardware_events": events[:100], "device_clocks": clocks,
                "samples": {"loadcell": n, "lost": {k: r.lost for k, r in self.logs.items()}}}
