"""Each claim under the model family: its range, the members at the range's ends, and whether the
model decides it (featherstar.optimizer.paper.report's table; family.py runs the experiments).

A claim's value under a member is the claims table computed from the report's data with that
member's results in place of the default model's (`member_data`), so every claim, its band and its
extra conditions (best above baseline, ...) are judged exactly as for the default model. The
verdict over the family (`classify`):
- *agrees robustly*: the claim agrees under every member (the whole range inside the band);
- *disagrees robustly*: it agrees under none and the range lies on one side of the band;
- *undecided by the model*: otherwise (the range straddles a band edge, or spans the band), or a
  member gave no value (a failed run), which is named: a missing member is never dropped.
"""
from __future__ import annotations

import math
from typing import Callable, Mapping

from .plan import FAMILY_STUDIES, MEMBER_BY_NAME, MORPHOLOGIES, Resolution

DEFAULT = "default"
AGREES, DISAGREES, UNDECIDED = "agrees robustly", "disagrees robustly", "undecided by the model"


def _finite(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def member_data(data: Mapping, name: str) -> dict:
    """The report's data as member `name` gives it. A re-validated optimum keeps the default's
    stroke and iterations; its validated TR stands for the estimate too (the member has no
    posterior of its own) and its baseline is the member's symmetric-stroke run. A feather the
    member does not change (no hinge on the plain feather) keeps the default's results."""
    member, runs = MEMBER_BY_NAME[name], data.get("family", {}).get(name, {})
    not_run = {"error": f"not run under {name}"}

    def pick(kind: str, key: str, family: str) -> dict:
        if not member.applies(family):
            return data[kind].get(key, {})
        return runs.get(kind, {}).get(key, not_run)

    symmetric = {f: pick("symmetric", f, f) for f in MORPHOLOGIES}
    studies = dict(data["studies"])
    for key in FAMILY_STUDIES:
        family = key.split("-")[0]
        study = pick("studies", key, family)
        if study.get("revalidated"):
            baseline = symmetric[family]
            study = {**data["studies"].get(key, {}), "estimated_thrust_ratio": study["summary"]["thrust_ratio"],
                     "summary": {**study["summary"], "baseline_thrust_ratio": baseline.get("thrust_ratio", math.nan),
                                 "baseline_thrust_ratio_sd": baseline.get("thrust_ratio_sd", math.nan)}}
        studies[key] = study
    robot = {f"{f}-{c}": pick("robot", f"{f}-{c}", f) for f in MORPHOLOGIES for c in ("best", "baseline", "worst")}
    return {**data, "symmetric": symmetric, "studies": studies, "robot": robot}


def classify(values: Mapping[str, float], verdicts: Mapping[str, bool | None], band: tuple[float, float],
             errors: Mapping[str, str] | None = None) -> tuple[str, str]:
    """The family's verdict on one claim and why, from each member's value and verdict (the
    default model among them)."""
    missing = [n for n in values if verdicts.get(n) is None or not _finite(values[n])]
    if missing:
        why = "; ".join(f"{n}: {(errors or {}).get(n) or 'no run recorded'}" for n in missing)
        return UNDECIDED, f"no value under {', '.join(missing)} ({why})"
    agree = [n for n in values if verdicts[n]]
    if len(agree) == len(values):
        return AGREES, "agrees under every member"
    lo, hi = band
    if not agree:
        if min(values.values()) < lo and max(values.values()) > hi:
            return UNDECIDED, "the members fall on both sides of the band"
        return DISAGREES, "agrees under no member"
    return UNDECIDED, f"agrees under {', '.join(agree)}; not under {', '.join(n for n in values if n not in agree)}"


# Claims read from one optimized stroke (the study that found it): re-validated, not re-optimized,
# a member's value bounds its own optimum from one side only.
REVALIDATED_OPTIMUM = {"chordwise_optimized": "chordwise-max", "spanwise_optimized": "spanwise-max",
                       "plain_optimized": "plain-max", "flapped_best": "chordwise-max", "flapped_worst": "chordwise-min",
                       "useful_thrust": "chordwise-max"}


def meaning(claim_id: str, res: Resolution) -> str:
    """What a claim's range is: the members' own answer, or the default's prediction re-measured."""
    reoptimized = lambda key: key in res.reoptimize  # noqa: E731
    optimum = lambda key: ("re-optimized under each member: the model's answer" if reoptimized(key)  # noqa: E731
                           else "the default's optimum validated under each member: the prediction's sensitivity")
    if claim_id.endswith("_symmetric"):
        return "the symmetric stroke re-run under each member: the model's answer"
    if claim_id in ("chordwise_optimized", "spanwise_optimized"):
        return optimum(claim_id.replace("_optimized", "-max")) + " (a validated TR, not an estimate)"
    if claim_id == "plain_optimized":
        return optimum("plain-max")
    if claim_id == "useful_thrust":
        return f"chordwise: {optimum('chordwise-max')}; plain: {optimum('plain-max')}"
    if claim_id in ("flapped_best", "flapped_worst"):
        return optimum("chordwise-max") + "; the baseline re-run"
    return "the default's controllers run under each member: the prediction's sensitivity (baseline: the model's answer)"


def family_table(data: Mapping, table: list[dict], res: Resolution, claims: Callable[[Mapping], list[dict]]) -> list[dict]:
    """`table` (the default model's claims) with each row's values under the family, its range, the
    members at its ends, the verdict and what the range means; unchanged when no family was run."""
    names = list(res.family)
    if not names:
        return table
    by_member = {name: claims(member_data(data, name)) for name in names}
    failures = data.get("failures", {})
    errors = {DEFAULT: "; ".join(f"{label}: {error}" for label, error in sorted(failures.items())
                                 if not label.startswith("family:"))[:300]}
    errors |= {name: "; ".join(f"{label.split(':', 2)[2]}: {error}" for label, error in sorted(failures.items())
                              if label.startswith(f"family:{name}:"))[:300] for name in names}
    out = []
    for i, row in enumerate(table):
        values = {DEFAULT: row["simulated"], **{n: by_member[n][i]["simulated"] for n in names}}
        verdicts = {DEFAULT: row["agrees"], **{n: by_member[n][i]["agrees"] for n in names}}
        verdict, why = classify(values, verdicts, tuple(row["band"]), errors)
        study = REVALIDATED_OPTIMUM.get(row["id"])
        if verdict == DISAGREES and study and study not in res.reoptimize:
            why += ("; the members' values are the default's optimum re-validated, and a member's own "
                    f"{'best' if study.endswith('max') else 'worst'} can only be "
                    f"{'higher' if study.endswith('max') else 'lower'}: re-optimizing could change this verdict")
        finite = {n: v for n, v in values.items() if _finite(v)}
        ends = [min(finite, key=finite.get), max(finite, key=finite.get)] if finite else [None, None]
        out.append({**row, "family": values, "family_agrees": verdicts,
                    "range": [finite[e] if e else math.nan for e in ends], "range_ends": ends,
                    "robust": verdict, "robust_reason": why, "range_meaning": meaning(row["id"], res)})
    return out
