"""The report's experiments under each member of the model family (`plan.MEMBERS`), as tasks.

What a claim's range means depends on what the claim is about, and the cost differs by orders of
magnitude, so each kind of experiment is redone differently (the report says which, per claim):
- a fixed stroke (the symmetric stroke, Fig. 5; the robot's baseline): re-run under the member,
  which is the member's own answer;
- an optimized stroke (Figs. 6, 8, and the robot's best and worst): the default model's optimum
  validated under the member, *the prediction's sensitivity* (the stroke is not the member's own
  best), except for the studies the resolution names in `reoptimize`, which are optimized afresh
  under the member, *the model's answer*.
Tasks are labelled `family:<member>:<kind>:<key>` and logged, resumed and run in parallel like
the rest of the report (`paper.run_experiments`).
"""
from __future__ import annotations

import dataclasses
from typing import Any, Callable, Mapping

from ..evaluation import validate
from ..objective import SceneObjective
from ..space import stroke_overrides, symmetric_stroke
from ..study import BEST_VALIDATION_INDEX
from .plan import (
    DEFAULT_RATIO,
    FAMILY_STUDIES,
    MEMBER_BY_NAME,
    MORPHOLOGIES,
    PERIOD_S,
    Member,
    Resolution,
    StudySpec,
    feather_overrides,
    study_specs,
)
from .tasks import measurement_plan, robot_controller, robot_task, study_task

Item = tuple[str, Callable, tuple]


def members(res: Resolution) -> list[Member]:
    return [MEMBER_BY_NAME[name] for name in res.family]


def validated_stroke_task(family: str, ratio: float | None, period_s: float, stroke: Mapping[str, Any],
                          member: Member, res: Resolution, index: tuple[int, ...]) -> dict:
    """A fixed stroke's validation (the report's sets of periods) under `member`; with the default
    model's index and no overrides it is the default's own validation, number for number."""
    objective = SceneObjective("testbed", {**feather_overrides(family, ratio), **dict(member.overrides)})
    out = validate(objective, dict(stroke), period_s, measurement_plan(res), index, repeats=res.validation_repeats,
                   periods=res.validation_periods).as_dict()
    out["sim_s"] = (res.settle_periods + res.validation_repeats * res.validation_periods) * period_s
    return out


def symmetric_item(family: str, member: Member, res: Resolution) -> Item:
    """Fig. 5's symmetric-stroke run under `member` (the same noise stream as the default's run)."""
    index = (100 + MORPHOLOGIES.index(family),)
    stroke = stroke_overrides(symmetric_stroke(PERIOD_S))
    return (f"family:{member.name}:fig5:{family}", validated_stroke_task,
            (family, DEFAULT_RATIO.get(family), PERIOD_S, stroke, member, res, index))


def reoptimize_task(spec: StudySpec, member: Member, res: Resolution) -> dict:
    """The default's own study (same seed, budget and validation) under `member`."""
    return study_task(spec, res, dict(member.overrides))


def labels(res: Resolution) -> list[str]:
    """Every family task this resolution plans (for the task log's check)."""
    out = []
    for member in members(res):
        out += [f"family:{member.name}:fig5:{f}" for f in MORPHOLOGIES if member.applies(f)]
        out += [f"family:{member.name}:{'study' if key in res.reoptimize else 'eval'}:{key}"
                for key in FAMILY_STUDIES if member.applies(key.split("-")[0])]
        out += [f"family:{member.name}:robot:{f}-{c}" for f in MORPHOLOGIES if member.applies(f)
                for c in ("best", "baseline", "worst")]
    return out


def backlog(res: Resolution) -> list[Item]:
    """The family tasks that need no study: symmetric runs, robot baselines, re-optimizations."""
    specs = study_specs(res)
    items: list[Item] = []
    for member in members(res):
        items += [(f"family:{member.name}:study:{key}", reoptimize_task, (specs[key], member, res))
                  for key in res.reoptimize if member.applies(key.split("-")[0])]
    for member in members(res):
        items += [symmetric_item(f, member, res) for f in MORPHOLOGIES if member.applies(f)]
        items += [(f"family:{member.name}:robot:{f}-baseline", robot_task,
                   (f, "baseline", {**robot_controller(f, "baseline", {}), **dict(member.overrides)}, res))
                  for f in MORPHOLOGIES if member.applies(f)]
    return items


def follow_ups(label: str, results: Mapping[str, dict], res: Resolution) -> tuple[list[Item], dict[str, dict]]:
    """After a default study: its optimum's validation and its robot runs under each member (tasks
    to queue), or, when the study failed, why they cannot run (results to record)."""
    kind, _, key = label.partition(":")
    if kind != "study" or key not in (f"{f}-{m}" for f in MORPHOLOGIES for m in ("max", "min")):
        return [], {}
    family, which = key.rsplit("-", 1)
    spec = study_specs(res)[key]
    study = results[label]
    items: list[Item] = []
    failed: dict[str, dict] = {}
    for member in members(res):
        if not member.applies(family):
            continue
        if key in FAMILY_STUDIES and key not in res.reoptimize:
            eval_label = f"family:{member.name}:eval:{key}"
            if "best_overrides" in study:
                items.append((eval_label, validated_stroke_task, (family, spec.ratio, spec.period_s,
                                                                  study["best_overrides"], member, res,
                                                                  BEST_VALIDATION_INDEX)))
            else:
                failed[eval_label] = {"error": f"skipped: its study failed ({study.get('error', 'no result')})"}
        controller = "best" if which == "max" else "worst"
        robot_label = f"family:{member.name}:robot:{family}-{controller}"
        overrides = robot_controller(family, controller, results)
        if isinstance(overrides, str):
            failed[robot_label] = {"error": overrides}
        else:
            items.append((robot_label, robot_task, (family, controller, {**overrides, **dict(member.overrides)}, res)))
    done = set(results)
    return ([item for item in items if item[0] not in done],
            {k: {**v, "wall_s": 0.0, "sim_s": 0.0} for k, v in failed.items() if k not in done})


def collect(results: Mapping[str, dict]) -> dict[str, dict]:
    """Family results by member: {"symmetric": {family: …}, "studies": {key: …}, "robot": {…}};
    a re-validated optimum comes as {"summary": its validation, "revalidated": True}."""
    out: dict[str, dict] = {}
    for label, result in results.items():
        kind, _, rest = label.partition(":")
        if kind != "family":
            continue
        name, what, key = rest.split(":", 2)
        member = out.setdefault(name, {"symmetric": {}, "studies": {}, "robot": {}})
        if what == "fig5":
            member["symmetric"][key] = result
        elif what == "eval":
            member["studies"][key] = result if "error" in result else {
                "summary": result, "revalidated": True, "wall_s": result.get("wall_s", 0.0), "sim_s": result.get("sim_s", 0.0)}
        elif what == "study":
            member["studies"][key] = result
        else:
            member["robot"][key] = result
    return out


def planned_simulated_s(res: Resolution) -> float:
    """Simulated seconds the family's tasks ask for (as `paper.planned_simulated_s`)."""
    specs = study_specs(res)
    validation_s = (res.settle_periods + res.validation_repeats * res.validation_periods)
    total = 0.0
    for member in members(res):
        for family in MORPHOLOGIES:
            if not member.applies(family):
                continue
            total += validation_s * PERIOD_S + 3 * res.robot_periods * PERIOD_S
            for key in FAMILY_STUDIES:
                if key.startswith(family + "-"):
                    spec = specs[key]
                    total += (spec.iterations * (res.settle_periods + res.periods) + 2 * validation_s) * spec.period_s \
                        if key in res.reoptimize else validation_s * spec.period_s
    return total


def describe(res: Resolution) -> list[dict]:
    return [{**dataclasses.asdict(m), "overrides": dict(m.overrides)} for m in members(res)]
