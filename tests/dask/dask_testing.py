"""Objectives and helpers the cluster tests ship to workers (importable there: workers start
with the test process's sys.path)."""
import os
import time
from dataclasses import dataclass

from featherstar.optimizer.synthetic import SyntheticFeather

FEATHER = SyntheticFeather("chordwise")


@dataclass(frozen=True)
class SlowFeather:
    """The synthetic feather, taking `delay_s` of wall time per run like a real simulation."""

    delay_s: float

    def __call__(self, overrides, duration_s):
        time.sleep(self.delay_s)
        return FEATHER(overrides, duration_s)


def without_timing(rows):
    """Rows without their wall-clock fields, which differ from run to run."""
    return [{k: v for k, v in r.items() if k not in ("sim_wall_s",)} for r in rows]


def fmu_run_on_this_worker():
    """A short plain-feather test-bed run through the FMU master, and what the FMU cache holds
    afterwards: (thrust ratio, pid, {fmu file: inode}, leftover partial files)."""
    from featherstar.fmu_src.export import cache_dir
    from featherstar.optimizer.evaluation import SWEEP_STREAM, MeasurementPlan, evaluate
    from featherstar.optimizer.objective import SceneObjective

    result = evaluate(SceneObjective("testbed", {"feather.morphology": "plain"}), {}, 1.5,
                      MeasurementPlan(settle_periods=0, periods=1), SWEEP_STREAM, (0,))
    fmus = {str(p.relative_to(cache_dir())): p.stat().st_ino for p in cache_dir().glob("*/*.fmu")}
    partial = [p.name for p in cache_dir().glob("*/*.part")]
    return result.thrust_ratio, os.getpid(), fmus, partial
