"""What the optimizer evaluates: the `Objective` protocol and its one adapter to the FMU master.

An objective runs one experiment: given scene overrides (controller times, morphology) and a run
length, it returns the thrust series the load cell would see. Noise and metrics are applied by
`featherstar.optimizer.evaluation`, the same way for every objective, so the optimizer never trusts a metric
computed elsewhere. Everything that knows how to call the master lives in this module.
"""
from __future__ import annotations

import functools
import importlib
import time
from dataclasses import dataclass, field
from typing import Any, Mapping, Protocol

import numpy as np

from .errors import OptimizerError

Overrides = Mapping[str, "str | float"]

# The master's run-length override (cosim.scene.MasterSpec.t_end_s).
RUN_LENGTH_OVERRIDE = "master.t_end_s"


@dataclass(frozen=True)
class Trace:
    """A recorded thrust series (upwards positive, tare removed) and what it cost to get."""

    time_s: np.ndarray
    thrust_N: np.ndarray
    wall_time_s: float


class Objective(Protocol):
    def __call__(self, overrides: Overrides, duration_s: float) -> Trace:
        """Run the experiment with these overrides for at least duration_s of simulated time."""


def preflight(objective: Objective, overrides: Overrides, duration_s: float) -> None:
    """Refuse, before any experiment runs, a setup the objective can tell cannot work: an
    objective may offer `check(overrides, duration_s)` (a scene's plan, built without simulating);
    one that does not is taken on trust."""
    check = getattr(objective, "check", None)
    if check is not None:
        check(overrides, duration_s)


def _master_api() -> tuple[Any, Any] | None:
    """(run_scene, load_scene) of the FMU master (featherstar.cosim.swimmer.run); None when it cannot be
    imported (a broken install: the optimizer's pure parts still work)."""
    try:
        api = importlib.import_module("featherstar.cosim.swimmer.run")
    except ImportError:
        return None
    return api.run_scene, api.load_scene


def _scene_plan(scene: Any, outputs: list[str]) -> Any:
    """The master's plan of a scene (every block resolved, wiring and signals checked; no FMU
    loaded, nothing simulated)."""
    return importlib.import_module("featherstar.cosim.scene.graph").plan(scene, outputs)


def master_available() -> bool:
    """Whether the FMU master's `run_scene` can be called in this install."""
    return _master_api() is not None


@functools.lru_cache(maxsize=8)
def _load_scene(scene: str) -> Any:
    """Scenes are loaded once per process: sweep workers get many tasks for one scene."""
    return _master_api()[1](scene)


@dataclass(frozen=True)
class SceneObjective:
    """Runs a cosim scene through the FMU master. Picklable (the scene is named and loaded in the
    process that runs it), so sweeps can ship it to worker processes or a Dask cluster."""

    scene: str
    overrides: Mapping[str, str | float] = field(default_factory=dict)
    thrust_signal: str = "feather.thrust_N"

    def check(self, overrides: Overrides, duration_s: float) -> None:
        """The run's plan, built and thrown away: an unknown override, a scene without the thrust
        signal (a robot with two feathers), bad wiring all stop here, before any run."""
        if _master_api() is None:
            raise OptimizerError("the FMU master is not available in this install")
        scene = _load_scene(self.scene).with_overrides({**self.overrides, **overrides, RUN_LENGTH_OVERRIDE: duration_s})
        _scene_plan(scene, [self.thrust_signal])

    def __call__(self, overrides: Overrides, duration_s: float) -> Trace:
        api = _master_api()
        if api is None:
            raise OptimizerError(
                "the FMU master (featherstar.cosim.run_scene / featherstar.cosim.load_scene) is not available in this install"
            )
        started = time.perf_counter()
        result = api[0](
            _load_scene(self.scene),
            {**self.overrides, **overrides, RUN_LENGTH_OVERRIDE: duration_s},
            outputs=[self.thrust_signal],
        )
        wall_s = time.perf_counter() - started
        return Trace(
            time_s=np.asarray(result.time, dtype=float),
            thrust_N=np.asarray(result.signals[self.thrust_signal], dtype=float),
            wall_time_s=float(result.summary.get("wall_time_s", wall_s)),
        )


@dataclass(frozen=True)
class WithOverrides:
    """Adds fixed overrides under the caller's own (which win on a clash)."""

    objective: Objective
    overrides: Mapping[str, str | float]

    def check(self, overrides: Overrides, duration_s: float) -> None:
        preflight(self.objective, {**self.overrides, **overrides}, duration_s)

    def __call__(self, overrides: Overrides, duration_s: float) -> Trace:
        return self.objective({**self.overrides, **overrides}, duration_s)
