"""Checks that refuse a run before any work when it cannot give a result: a run whose recorded
signals would not fit in memory, a metric window with no whole period, a metric period spanning
too few samples (an FMU archive's checks are featherstar.cosim.fmi.archive)."""
from __future__ import annotations

import logging
import os

from ..errors import SceneError
from .plan import Plan

log = logging.getLogger(__name__)

MEMORY_FRACTION = 0.5       # of the memory available now: leave room for FMUs and the figure
_BYTES_PER_VALUE = 40       # a Python float in a row list (24 + 8) plus its numpy copy (8)
_BYTES_PER_ROW = 120        # the row list, the time stamp and the CSV/figure copies
#: A metric period must span this many recorded samples: the per-period thrust ratio integrates
#: each period's positive and negative thrust apart, and a stroke has four phases.
MIN_SAMPLES_PER_PERIOD = 20


def available_memory_bytes() -> int:
    """MemAvailable from /proc/meminfo, else physical memory."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def _human(n_bytes: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n_bytes < 1024 or unit == "PiB":
            return f"{n_bytes:.1f} {unit}"
        n_bytes /= 1024
    return f"{n_bytes:.1f} PiB"


def run_length_setting(plan: Plan) -> str:
    """The key that sets the run's length, as the user set it: master.t_end_s when it is set
    (it overrides master.periods), else master.periods."""
    master = plan.scene.master
    return f"master.t_end_s = {master.t_end_s:g}" if master.t_end_s else f"master.periods = {master.periods:g}"


def check_run_size(plan: Plan, available_bytes: int | None = None) -> None:
    """Refuse a run whose recorded rows would not fit in memory, naming the run length."""
    master = plan.scene.master
    grid_s = master.output_interval_s if master.coupling == "strong" else master.step_s
    n_rows = plan.t_end_s / grid_s + 1
    n_cols = len(plan.requested)
    need = n_rows * (_BYTES_PER_ROW + _BYTES_PER_VALUE * n_cols)
    have = available_memory_bytes() if available_bytes is None else available_bytes
    if need > MEMORY_FRACTION * have:
        raise SceneError(f"{run_length_setting(plan)} ({plan.t_end_s:.3g} s of simulated time) would record "
                         f"{n_rows:.3g} points x {n_cols} signals, about {_human(need)}; "
                         f"{_human(have)} of memory is available: shorten the run, record "
                         "fewer signals (--record) or coarsen the recording grid",
                         plan.scene.name)


def check_metric_window(plan: Plan) -> None:
    """Refuse a metric period spanning fewer than MIN_SAMPLES_PER_PERIOD recorded samples, and a
    settling time that leaves no whole period to measure (the metrics would silently fall back
    to the transient)."""
    metrics, period_s = plan.scene.metrics, plan.period_s
    if not period_s or not metrics.thrust:
        return
    master = plan.scene.master
    grid_s = master.output_interval_s if master.coupling == "strong" else master.step_s
    grid_key = "master.output_interval_s" if master.coupling == "strong" else "master.step_s"
    if period_s / grid_s < MIN_SAMPLES_PER_PERIOD:
        what = (f"metrics.period_s = {metrics.period_s:g}" if metrics.period_s
                else f"the stroke period ({period_s:g} s)")
        raise SceneError(f"{what} spans {period_s / grid_s:.3g} samples of {grid_key} = {grid_s:g} s; a "
                         f"metric period needs at least {MIN_SAMPLES_PER_PERIOD}: refine the grid or "
                         "lengthen the period", plan.scene.name)
    run_periods = plan.t_end_s / period_s
    if metrics.settle_periods + 1 > run_periods + 1e-9:
        raise SceneError(f"metrics.settle_periods = {metrics.settle_periods:g} leaves no whole "
                         f"period to measure in a run of {run_periods:.3g} periods; lower it "
                         f"to at most {max(run_periods - 1, 0):.3g} or lengthen the run "
                         f"({run_length_setting(plan)})",
                         plan.scene.name)
