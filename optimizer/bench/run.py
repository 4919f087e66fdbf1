"""One stroke on the bench: the only place the optimizer calls the master with hardware.

`run_on_bench` runs a scene with its servo and load cell swapped for devices (as
`featherstar run --hardware` does: `featherstar.hil.hardware.with_hardware` +
`featherstar.hil.timed_run.run_bench_scene`, streamed or device-timed) and
returns what the bench recorded and the master's verdict on it. Everything hardware-facing in
the optimizer (the bench study, calibration recordings, the bench in bench/) goes through this
function, so moving to another way of stepping the master changes this module only.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ...cosim.errors import StepError
from ...cosim.scenes import load_scene
from ...cosim.swimmer.metrics import READ_TIME_PORT, sample_times
from ...hil.hardware import LOADCELL_BLOCK, check_hardware_overrides, parse_hardware, with_hardware
from ...hil.timed_run import is_device_timed, run_bench_scene
from ..errors import OptimizerError

THRUST_SIGNAL = f"{LOADCELL_BLOCK}.thrust_N"
READ_TIME_SIGNAL = f"{LOADCELL_BLOCK}.{READ_TIME_PORT}"   # when a streamed run read each sample
ANGLE_SIGNAL = "servo.angle_rad"


class BenchFault(OptimizerError):
    """A device failed during a bench run (timeout, lost link, error bit, unsafe stop)."""

    def __init__(self, message: str, *, block: str = "", t_s: float | None = None) -> None:
        super().__init__(message)
        self.block = block
        self.t_s = t_s


@dataclass(frozen=True)
class BenchRun:
    """What the bench recorded: load-cell thrust (tared, N) and servo angle (rad) on `time_s`
    (when each thrust sample was taken: the device's clock, or the PC's at the read of a
    streamed run), and the master's summary (validity, deadline misses, gaps, safe position)."""

    time_s: np.ndarray
    thrust_N: np.ndarray
    angle_rad: np.ndarray
    summary: dict[str, Any]
    complete: bool


def run_on_bench(scene: str, hardware: Mapping[str, str], overrides: Mapping[str, str | float]) -> BenchRun:
    """Run `scene` with `overrides` on the devices in `hardware` ({"servo": URL, "loadcell": URL})
    in real time. Raises BenchFault when a device fails (the servo was commanded to its safe
    position by the master on the way out) or does not acknowledge its safe position at the end,
    KeyboardInterrupt when the run was interrupted, SceneError for a bad scene or URL."""
    slots = parse_hardware([f"{slot}={url}" for slot, url in hardware.items()])
    if set(slots) != {"servo", "loadcell"}:
        raise OptimizerError("a bench run needs both --hardware servo=URL and --hardware loadcell=URL")
    # The hardware blocks report every fault themselves; pymodbus' log of it would only bury it.
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    bench_scene = with_hardware(load_scene(scene), slots)
    check_hardware_overrides(bench_scene, overrides)
    try:
        # streamed, or device-timed when the URLs say clock=device (docs/hil.md)
        outputs = [THRUST_SIGNAL, ANGLE_SIGNAL] + ([] if is_device_timed(bench_scene) else [READ_TIME_SIGNAL])
        result = run_bench_scene(bench_scene, dict(overrides), outputs=outputs)
    except StepError as exc:
        if exc.interrupted:
            raise KeyboardInterrupt(exc.interrupted) from exc
        raise BenchFault(f"device fault: {exc}", block=exc.block, t_s=exc.t_s) from None
    unsafe = [name for name, ok in (result.summary.get("safe_position_confirmed") or {}).items() if not ok]
    if unsafe:
        raise BenchFault(f"{', '.join(unsafe)} did not acknowledge its safe position after the run; "
                         "check the servo by hand", block=unsafe[0])
    time_s, _ = sample_times(np.asarray(result.time, dtype=float), result.signals, THRUST_SIGNAL)
    return BenchRun(
        time_s=time_s,
        thrust_N=np.asarray(result[THRUST_SIGNAL], dtype=float),
        angle_rad=np.asarray(result[ANGLE_SIGNAL], dtype=float),
        summary=result.summary,
        complete=result.complete,
    )
