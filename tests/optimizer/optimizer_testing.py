"""Shared setup of the optimizer tests (imported by conftest and by the tests)."""
import json

from featherstar.optimizer.evaluation import MeasurementPlan
from featherstar.optimizer.space import stroke_space
from featherstar.optimizer.synthetic import SyntheticFeather

FEATHER = SyntheticFeather("chordwise")
SPACE = stroke_space(1.5)
PLAN = MeasurementPlan(seed=7)
SHORT_ITERATIONS = 14


def logged_evaluations(path):
    """Logged evaluations without their wall-clock timings (nor the digest, which covers them)."""
    records = [json.loads(line) for line in path.read_text().splitlines()[1:]]
    return [{k: v for k, v in r.items() if k not in ("sim_wall_s", "digest")} for r in records
            if r["kind"] == "evaluation"]


class FailingForWideFeathers:
    """A synthetic feather whose 'simulation' fails above WR 10 (picklable for workers)."""

    def __call__(self, overrides, duration_s):
        if float(overrides.get("feather.width_ratio", 0.0)) > 10.0:
            raise RuntimeError("solver failure (on purpose)")
        return FEATHER(overrides, duration_s)


def always_failing(overrides, duration_s):
    raise RuntimeError("no master here")


class Interrupting:
    """The synthetic feather, but Ctrl-C (KeyboardInterrupt) in the middle of experiment number
    `at` (1-based, counted in this process)."""

    def __init__(self, at):
        self.calls, self.at = 0, at

    def __call__(self, overrides, duration_s):
        self.calls += 1
        if self.calls == self.at:
            raise KeyboardInterrupt
        return FEATHER(overrides, duration_s)
