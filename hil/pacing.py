"""Wall-clock pacing for runs with hardware in the loop.

With a real servo and load cell, simulation time must follow the wall clock: the bench does not
wait. `Pacer` keeps a fixed grid of ticks t_k = k * period_s after the first one and sleeps to
each. A step that ends after the next tick was due is a deadline miss; the pacer then goes on
with the latest tick already due (starting it late) and skips any tick wholly passed, so time
never drifts behind the wall clock. The step length h_s handed out grows by the skipped periods.

A scene with hardware blocks (`master.realtime`) is paced by the Simulator itself
(featherstar.cosim.coupling.pacing, before every macro step). `run_paced` is for driving hardware blocks directly,
without a scene: the bench's loop-rate measurement (bench/hil_loop_rate.py) and the fault tests.
"""
from __future__ import annotations

import datetime as _dt
import math
import time
from array import array
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

from .recorder import Recorder


@dataclass(frozen=True)
class Tick:
    index: int          # grid index k
    t_s: float          # grid time k * period_s
    h_s: float          # time since the previous tick (0 for the first): the step to take now
    wall_s: float       # monotonic time at which the tick started, since the first tick
    late_s: float       # wall_s - t_s (wake-up jitter, or the overrun of the previous step)
    skipped: int        # grid ticks skipped just before this one


@dataclass
class PacerStats:
    period_s: float
    n_ticks: int = 0
    n_misses: int = 0           # steps that ended after the next tick was due
    n_skipped: int = 0          # grid ticks never run
    late_s: array = field(default_factory=lambda: array("d"))
    busy_s: array = field(default_factory=lambda: array("d"))   # tick start -> next wait()

    def summary(self) -> dict[str, float]:
        def q(values: array, p: float) -> float:
            if not values:
                return math.nan
            ordered = sorted(values)
            return ordered[min(len(ordered) - 1, int(p * len(ordered)))]
        return {
            "period_s": self.period_s, "n_ticks": self.n_ticks, "n_misses": self.n_misses,
            "n_skipped": self.n_skipped,
            "miss_fraction": self.n_misses / max(self.n_ticks - 1, 1),
            "late_p50_s": q(self.late_s, 0.5), "late_p99_s": q(self.late_s, 0.99),
            "late_max_s": max(self.late_s, default=math.nan),
            "busy_p50_s": q(self.busy_s, 0.5), "busy_p99_s": q(self.busy_s, 0.99),
            "busy_max_s": max(self.busy_s, default=math.nan),
            "busy_fraction": sum(self.busy_s) / (self.period_s * max(len(self.busy_s), 1)),
        }


class Pacer:
    """Call `wait()` at the top of each step; it returns the tick to run, or None once the
    last tick, at `end_s` (inclusive; None = run forever), has run. A step that overruns into
    the end still gets the last tick (late), so a run always ends at `end_s`.

    `clock` and `sleep` are the wall clock's (time.monotonic, time.sleep); a test passes a
    simulated clock to check the pacing logic whatever the machine's load."""

    def __init__(self, period_s: float, end_s: float | None = None, *,
                 clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        if not period_s > 0:
            raise ValueError(f"period_s must be positive, got {period_s}")
        self.period_s = period_s
        self._clock, self._sleep = clock, sleep
        # Half a period of slack so that k * period_s rounding never drops the last tick.
        self._last_k = math.inf if end_s is None else math.floor(end_s / period_s + 0.5)
        self.stats = PacerStats(period_s)
        self.t0_mono: float | None = None
        self._k = 0
        self._tick_start = 0.0

    def wait(self) -> Tick | None:
        now = self._clock()
        if self.t0_mono is None:
            self.t0_mono = self._tick_start = now
            self.stats.n_ticks, self.stats.late_s = 1, array("d", [0.0])
            return Tick(0, 0.0, 0.0, 0.0, 0.0, 0)
        t0, p, k = self.t0_mono, self.period_s, self._k
        self.stats.busy_s.append(now - self._tick_start)
        if k + 1 > self._last_k:
            return None
        due = t0 + (k + 1) * p
        overran = now > due
        if not overran:
            self._sleep(due - now)
            now = self._clock()
        j = min(max(k + 1, math.floor((now - t0) / p)), self._last_k)
        skipped = j - (k + 1)
        self.stats.n_ticks += 1
        self.stats.n_misses += overran or skipped > 0
        self.stats.n_skipped += skipped
        late_s = now - (t0 + j * p)
        self.stats.late_s.append(late_s)
        self._k, self._tick_start = j, now
        return Tick(j, j * p, (j - k) * p, now - t0, late_s, skipped)


@dataclass(frozen=True)
class RunResult:
    out_dir: Path
    samples_csv: Path
    n_samples: int
    stats: dict[str, float]


def run_paced(step: Callable[[float, float], Mapping[str, float]], rate_hz: float,
              duration_s: float, out_dir: str | Path, *, flush_s: float = 0.5,
              meta: Mapping[str, object] | None = None) -> RunResult:
    """Run `step` on a wall-clock grid of `rate_hz` from t = 0 to `duration_s` inclusive and
    record every sample under `out_dir`.

    `step(t_s, h_s)` is called once per tick: the wall clock has reached grid time t_s, h_s
    after the previous tick (h_s = 0 on the first call, where the master only reads outputs;
    h_s is a multiple of the period, larger than one period after a deadline miss). The master
    advances its blocks from t_s - h_s by h_s (for hardware blocks, do_step does the bus I/O),
    sets new inputs, and returns the sample to record: a flat mapping of floats whose keys are
    fixed by the first call. Keep the step well inside the period: hardware I/O over loopback
    takes 0.3-1 ms per device; see bench/hil_loop_rate.py.

    Written under out_dir: samples.csv (columns t_s, wall_s, late_s, step_s, then the step's
    keys; flushed every flush_s), run.json (rate, pacing statistics, `meta`, start time), and
    fault.json if the run stops on an exception (a DeviceFault names the device, the fault
    and the time). The exception is re-raised after the records are safe; the caller still
    owns its blocks and must close() them (which commands the servo's safe position).
    """
    if not rate_hz > 0 or not duration_s >= 0:
        raise ValueError(f"need rate_hz > 0 and duration_s >= 0, got {rate_hz}, {duration_s}")
    pacer = Pacer(1.0 / rate_hz, end_s=duration_s)
    info: dict[str, object] = {
        "rate_hz": rate_hz, "duration_s": duration_s, "meta": dict(meta or {}),
        "started": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="milliseconds")}
    with Recorder(out_dir, flush_s=flush_s) as recorder:
        try:
            while (tick := pacer.wait()) is not None:
                t_start = time.monotonic()
                sample = step(tick.t_s, tick.h_s)
                recorder.write({"t_s": tick.t_s, "wall_s": tick.wall_s, "late_s": tick.late_s,
                                "step_s": time.monotonic() - t_start, **sample})
        except BaseException as exc:
            recorder.write_fault(exc)
            info["fault"] = "fault.json"
            raise
        finally:
            info.update(t0_monotonic_s=pacer.t0_mono, n_samples=recorder.n_rows,
                        stats=pacer.stats.summary())
            recorder.write_json("run.json", info)
    return RunResult(Path(out_dir), recorder.samples_csv, recorder.n_rows, pacer.stats.summary())
