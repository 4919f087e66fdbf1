"""The paper report's model-form uncertainty without a master: the family's task plan, each claim
under each member from fake results, and the verdict at the band's edges (robustness.classify)."""
import dataclasses
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from featherstar.optimizer.paper import family
from featherstar.optimizer.paper.paper import collect
from featherstar.optimizer.paper.plan import FAMILY_STUDIES, MORPHOLOGIES, QUICK, Resolution
from featherstar.optimizer.paper.report import claims
from featherstar.optimizer.paper.robustness import AGREES, DEFAULT, DISAGREES, UNDECIDED, classify, family_table

RES = dataclasses.replace(QUICK, family=("wake-self", "hinge-1e-3"), reoptimize=("plain-max",))
STROKE = {"t_up_s": 0.5, "t_hold_up_s": 0.25, "t_down_s": 0.5, "t_hold_down_s": 0.25}


def _study(tr: float, baseline: float = 1.5) -> dict:
    return {"best_overrides": {"controller.t_up_s": 0.5}, "estimated_thrust_ratio": tr, "evaluations": [{}] * 30,
            "stroke": STROKE, "summary": {"thrust_ratio": tr, "thrust_ratio_sd": 0.01, "mean_thrust_N": 0.01,
                                          "baseline_thrust_ratio": baseline, "baseline_thrust_ratio_sd": 0.01}}


def _symmetric(tr: float) -> dict:
    return {"thrust_ratio": tr, "thrust_ratio_sd": 0.01, "mean_thrust_N": 0.02, "peak_thrust_N": [-0.1, 0.2],
            "max_fold_deg": 90.0}


def _results(plain_tr: dict[str, float], failed: dict[str, str] = {}) -> dict:
    """Every task of RES: the plain feather's optimized TR per member as given, the rest fixed."""
    out = {f"fig5:{f}": _symmetric(tr) for f, tr in (("plain", 1.0), ("chordwise", 2.0), ("spanwise", 2.2))}
    out |= {f"study:{f}-{m}": _study(tr) for f in MORPHOLOGIES for m, tr in (("max", 3.5), ("min", 1.2))}
    out["study:plain-max"] = _study(plain_tr[DEFAULT])
    out |= {f"robot:{f}-{c}": {"mean_speed_m_s": v} for f in MORPHOLOGIES for c, v in
            (("best", 0.02), ("baseline", 0.01), ("worst", 0.001))}
    for label in family.labels(RES):
        name, kind, key = label.split(":")[1:]
        if kind == "fig5":
            out[label] = out[f"fig5:{key}"]
        elif kind == "eval":
            out[label] = out[f"study:{key}"]["summary"]
        elif kind == "study":
            out[label] = _study(plain_tr[name])
        else:
            out[label] = out[f"robot:{key}"]
    out |= {label: {"error": error} for label, error in failed.items()}
    return out


def _row(table: list[dict], id_: str) -> dict:
    return next(row for row in table if row["id"] == id_)


def _table(results: dict) -> list[dict]:
    data = collect(results)
    return family_table(data, claims(data), RES, claims)


def test_a_claim_is_judged_under_every_member_and_named_at_its_ends():
    table = _table(_results({DEFAULT: 1.38, "wake-self": 0.99}))
    row = _row(table, "plain_optimized")
    # hinge-1e-3 does not exist on the plain feather: it keeps the default's re-optimized value
    assert row["family"] == {DEFAULT: 1.38, "wake-self": 0.99, "hinge-1e-3": 1.38}
    assert row["range"] == [0.99, 1.38] and row["range_ends"] == ["wake-self", DEFAULT]
    assert row["robust"] == UNDECIDED and "wake-self" in row["robust_reason"]
    assert "re-optimized" in row["range_meaning"] and "sensitivity" in _row(table, "chordwise_optimized")["range_meaning"]
    assert _row(table, "plain_symmetric")["robust"] == AGREES
    assert _row(table, "chordwise_optimized")["robust"] == AGREES            # 3.5 in 3–5.5 under every member
    assert _row(table, "spanwise_optimized")["robust"] == DISAGREES          # 3.5 above 2–3.2 under every member


def test_a_failed_member_run_makes_its_claims_undecided_and_says_why():
    table = _table(_results({DEFAULT: 1.0, "wake-self": 1.0},
                            failed={"family:wake-self:fig5:spanwise": "StepError: boom"}))
    row = _row(table, "spanwise_symmetric")
    assert row["robust"] == UNDECIDED and math.isnan(row["family"]["wake-self"])
    assert "wake-self" in row["robust_reason"] and "StepError: boom" in row["robust_reason"]
    assert _row(table, "chordwise_symmetric")["robust"] == AGREES   # the failure touches only what it feeds
    # the spanwise baseline under wake-self is gone, so "best above baseline" cannot be judged there either
    assert _row(table, "flapped_best")["robust"] == UNDECIDED


def test_a_missing_member_run_is_not_silently_dropped():
    results = _results({DEFAULT: 1.0, "wake-self": 1.0})
    del results["family:hinge-1e-3:robot:chordwise-best"]
    row = _row(_table(results), "robot_chordwise")
    assert row["robust"] == UNDECIDED and "hinge-1e-3" in row["robust_reason"]


@pytest.mark.parametrize("values, verdict", [
    ((1.0, 1.15), AGREES),            # both band edges belong to the band
    ((1.0, 1.1500001), UNDECIDED),    # just over the edge: straddles it
    ((1.16, 1.3), DISAGREES),
    ((-0.1, 1.3), UNDECIDED),         # out on both sides: the range spans the band
    ((1.0, math.nan), UNDECIDED),
])
def test_the_verdict_at_the_band_edges(values, verdict):
    band = (0.0, 1.15)
    named = dict(zip((DEFAULT, "m"), values))
    verdicts = {n: (band[0] <= v <= band[1]) if math.isfinite(v) else None for n, v in named.items()}
    assert classify(named, verdicts, band)[0] == verdict


@given(st.lists(st.one_of(st.floats(-5, 5), st.just(math.nan)), min_size=1, max_size=9),
       st.floats(-3, 3), st.floats(0, 3))
def test_the_verdict_follows_the_range(values, lo, width):
    band = (lo, lo + width)
    named = {f"m{i}": v for i, v in enumerate(values)}
    verdicts = {n: None if math.isnan(v) else band[0] <= v <= band[1] for n, v in named.items()}
    verdict, why = classify(named, verdicts, band)
    finite = [v for v in values if not math.isnan(v)]
    if len(finite) < len(values):
        assert verdict == UNDECIDED and all(n in why for n, v in named.items() if math.isnan(v))
    elif band[0] <= min(finite) and max(finite) <= band[1]:
        assert verdict == AGREES
    elif max(finite) < band[0] or min(finite) > band[1]:
        assert verdict == DISAGREES
    else:
        assert verdict == UNDECIDED


def test_every_family_task_is_planned_and_a_failed_study_stops_its_follow_ups():
    planned = set(family.labels(RES))
    labels = [label for label, _, _ in family.backlog(RES)]
    results = {f"study:{f}-{m}": _study(2.0) for f in MORPHOLOGIES for m in ("max", "min")}
    for label in list(results):
        items, failed = family.follow_ups(label, results, RES)
        assert not failed
        labels += [item[0] for item in items]
    assert len(labels) == len(set(labels)) and set(labels) == planned
    assert {f"family:wake-self:eval:{k}" for k in FAMILY_STUDIES if k != "plain-max"} <= planned
    assert "family:hinge-1e-3:fig5:plain" not in planned           # no hinge on the plain feather
    _, failed = family.follow_ups("study:chordwise-max", {"study:chordwise-max": {"error": "StepError: x"}}, RES)
    assert set(failed) == {"family:wake-self:eval:chordwise-max", "family:hinge-1e-3:eval:chordwise-max",
                           "family:wake-self:robot:chordwise-best", "family:hinge-1e-3:robot:chordwise-best"}
    assert all("StepError: x" in r["error"] for r in failed.values())


def test_a_resolution_names_only_known_members_and_studies():
    with pytest.raises(ValueError, match="wake-sideways"):
        dataclasses.replace(QUICK, family=("wake-sideways",))
    with pytest.raises(ValueError, match="reoptimize"):
        dataclasses.replace(QUICK, reoptimize=("plain-sideways",))
    assert isinstance(RES, Resolution) and family.planned_simulated_s(RES) > 0
