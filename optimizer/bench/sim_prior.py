"""A simulated study as the prior of a bench study: its best strokes become the bench's initial design.

Transfer chosen: the bench study's `n_initial_points` (random points in a study without prior)
are the simulated study's best evaluated strokes, best first, kept apart by at least
`MIN_SEPARATION` of each variable's range; after them the GP is fitted on bench data only.

Why not put the simulated TR values into the bench's GP (as data, or as a second fidelity)?
The model's TR is off by up to a factor of two against the paper's bench (README: chordwise
optimized TR 1.73 vs ≈ 4), and calibrated coefficients only shrink that gap. Simulated values
told as measurements pull the GP's mean toward the simulator where the bench has not been
measured yet; a second fidelity needs a multi-task kernel the ask/tell optimizer does not have,
and the bench correlation it must learn costs more bench runs than a 30-iteration study has. What
does transfer is *where* the good strokes are (the mechanisms behind them, slow upstroke and
fast downstroke, are the same), and that is what the initial design uses. It costs nothing when
the prior is wrong beyond those few runs: the GP then explores as without a prior.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import OptimizerError
from ..evaluation import MeasurementPlan
from ..loadcell import LoadCell
from ..log import ExperimentLog
from ..resume import Entries, check_log
from ..objective import Objective, SceneObjective, WithOverrides
from ..space import SearchSpace
from ..synthetic import SyntheticFeather

MIN_SEPARATION = 0.1   # of each variable's range: initial points must not all sit on one spot
_GEOMETRY = {"chordwise": "feather.width_ratio", "spanwise": "feather.length_ratio"}
_SYNTHETIC = "synthetic:"


def study_morphology(scene: str, overrides: Mapping[str, Any]) -> dict[str, Any]:
    """The feather a study measured: {"morphology": ..., and its WR or LR when it has one}."""
    if scene.startswith(_SYNTHETIC):
        morphology, parameters = scene[len(_SYNTHETIC):], {}
    else:
        from ...cosim.scenes import load_scene

        feather = load_scene(scene).to_dict()["blocks"].get("feather")
        if feather is None:
            raise OptimizerError(f"scene '{scene}' has no 'feather' block: its morphology is unknown")
        morphology = str(feather.get("options", {}).get("morphology", "plain"))
        parameters = {f"feather.{k}": v for k, v in feather.get("parameters", {}).items()}
    morphology = str(overrides.get("feather.morphology", morphology))
    described: dict[str, Any] = {"morphology": morphology}
    if morphology in _GEOMETRY:
        key = _GEOMETRY[morphology]
        value = overrides.get(key, parameters.get(key))
        if value is not None:
            described[key] = float(value)
    return described


# A simulated study's log, read as data: its evaluations (the prior) and estimates, each once.
PRIOR_ENTRIES = (
    Entries("evaluation", {"index": "int", "params": "dict", "thrust_ratio": "number"}, key="index"),
    Entries("estimate", {"index": "int", "params": "dict", "thrust_ratio": "number"}, key="index"),
)


@dataclass(frozen=True)
class SimPrior:
    """The evaluations of a simulated study (`featherstar optimize` output directory)."""

    directory: Path
    feather: dict[str, Any]
    points: tuple[dict[str, float], ...]
    values: tuple[float, ...]
    maximize: bool
    context: dict[str, Any] = field(default_factory=dict)       # its scene and overrides
    measurement: dict[str, Any] = field(default_factory=dict)   # its settling and measured periods

    @classmethod
    def load(cls, directory: str | Path, *, feather: Mapping[str, Any], space: SearchSpace,
             maximize: bool) -> "SimPrior":
        """Read DIR/evaluations.jsonl; refuse a study of another feather, space or objective."""
        directory = Path(directory)
        path = directory / "evaluations.jsonl"
        if not path.is_file():
            raise OptimizerError(f"--prior {directory}: no evaluations.jsonl there (give a `featherstar optimize` "
                                 "output directory)")
        try:
            header, log = ExperimentLog.read(path)
            check_log(log, PRIOR_ENTRIES)
        except OptimizerError as exc:
            raise OptimizerError(f"--prior {directory}: {exc}") from None
        if "context" not in header or not isinstance(header["context"], dict):
            raise OptimizerError(f"--prior {directory}: evaluations.jsonl has no study header")
        if header.get("measured"):
            raise OptimizerError(f"--prior {directory}: that is a bench study; the prior must be a simulated one")
        context = header["context"]
        theirs = study_morphology(str(context.get("scene", "")), context.get("overrides") or {})
        if theirs != dict(feather):
            raise OptimizerError(f"--prior {directory}: it optimized a {_name(theirs)} feather, this study "
                                 f"measures a {_name(feather)} one")
        if bool(header.get("maximize")) != maximize:
            raise OptimizerError(f"--prior {directory}: it {'maximized' if header.get('maximize') else 'minimized'} "
                                 f"TR, this study {'maximizes' if maximize else 'minimizes'} it")
        their_space = header.get("space") or {}
        ours = space.describe()
        for key in ("period_s", "amplitude_deg"):
            if not math.isclose(float(their_space.get(key, math.nan)), float(ours[key]), rel_tol=1e-9):
                raise OptimizerError(f"--prior {directory}: its stroke {key} is {their_space.get(key)}, this "
                                     f"study's is {ours[key]}")
        records = [r for r in log.records if r["kind"] == "evaluation" and not isinstance(r["thrust_ratio"], str)]
        if not records:
            raise OptimizerError(f"--prior {directory}: no evaluations logged")
        missing = [n for n in space.names if any(not isinstance(r["params"].get(n), (int, float)) for r in records)]
        if missing:
            raise OptimizerError(f"--prior {directory}: its evaluations have no {', '.join(missing)}")
        return cls(directory, dict(feather), tuple({n: float(r["params"][n]) for n in space.names} for r in records),
                   tuple(float(r["thrust_ratio"]) for r in records), maximize, dict(context),
                   dict(header.get("measurement") or {}))

    def initial_points(self, space: SearchSpace, n: int, *, maximize: bool) -> list[dict[str, float]]:
        """Up to `n` of the best simulated strokes inside `space`, best first, each at least
        MIN_SEPARATION (in range-normalised coordinates) from those before it."""
        low, high = np.array(space.bounds).T
        order = np.argsort(self.values)[:: -1 if maximize else 1]
        chosen: list[np.ndarray] = []
        points = []
        for i in order:
            point = self.points[i]
            if not space.is_feasible(point):
                continue
            x = (np.array(space.vector(point)) - low) / (high - low)
            if all(np.max(np.abs(x - c)) >= MIN_SEPARATION for c in chosen):
                chosen.append(x)
                points.append(dict(point))
            if len(points) == n:
                break
        return points

    def simulation(self) -> tuple[Objective, MeasurementPlan]:
        """The simulated study's own simulation (its scene and overrides) and its measurement
        window, read without noise: what a discrepancy prior simulates at each bench stroke."""
        scene = str(self.context.get("scene", ""))
        overrides = dict(self.context.get("overrides") or {})
        if not scene:
            raise OptimizerError(f"--prior {self.directory}: its header names no scene to simulate")
        objective: Objective = (WithOverrides(SyntheticFeather(morphology=scene[len(_SYNTHETIC):]), overrides)
                                if scene.startswith(_SYNTHETIC) else SceneObjective(scene, overrides))
        m = self.measurement
        plan = MeasurementPlan(load_cell=LoadCell(noise_sd_N=0.0, sample_rate_hz=float(m.get("sample_rate_hz", LoadCell().sample_rate_hz))),
                               settle_periods=int(m.get("settle_periods", 3)), periods=int(m.get("periods", 5)))
        return objective, plan

    def describe(self) -> dict:
        best = int(np.argmax(self.values) if self.maximize else np.argmin(self.values))
        return {"directory": str(self.directory.resolve()), "feather": self.feather, "evaluations": len(self.points),
                "best_simulated_thrust_ratio": self.values[best], "transfer": "initial design from the best strokes"}


def _name(feather: Mapping[str, Any]) -> str:
    extra = ", ".join(f"{k.split('.')[-1]} {v:g}" for k, v in feather.items() if k != "morphology")
    return f"{feather['morphology']}" + (f" ({extra})" if extra else "")
