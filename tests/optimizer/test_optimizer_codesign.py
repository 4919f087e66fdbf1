import json

import pytest
from optimizer_testing import FEATHER

from featherstar.optimizer.codesign import codesign
from featherstar.optimizer.errors import OptimizerError
from featherstar.optimizer.evaluation import MeasurementPlan


def test_joint_and_two_stage_spend_the_same_budget(tmp_path):
    report = codesign(FEATHER, "chordwise", tmp_path, budget=12, plan=MeasurementPlan(seed=1))
    assert 1.5 <= report["joint"]["ratio"] <= 12.0
    assert len(report["two_stage"]["stage1"]) == 4
    joint_log = (tmp_path / "joint" / "evaluations.jsonl").read_text()
    stage2_log = (tmp_path / "two_stage" / "evaluations.jsonl").read_text()
    assert joint_log.count('"evaluation"') == 12 and stage2_log.count('"evaluation"') == 8
    assert json.loads((tmp_path / "codesign.json").read_text())["budget"] == 12
    for approach in ("joint", "two_stage"):
        assert report[approach]["thrust_ratio"] > 1.0


def test_bad_codesign_requests():
    with pytest.raises(OptimizerError, match="unknown morphology family"):
        codesign(FEATHER, "radial", "unused")
    with pytest.raises(OptimizerError, match="stage 1 needs"):
        codesign(FEATHER, "spanwise", "unused", budget=6, stage1_experiments=5)


def test_stage1_is_logged_and_a_resume_runs_only_what_it_lacks(tmp_path):
    plan = MeasurementPlan(seed=1)
    report = codesign(FEATHER, "chordwise", tmp_path, budget=8, plan=plan)
    log = tmp_path / "stage1.jsonl"
    lines = log.read_text().splitlines()
    assert len(lines) == 1 + 2
    log.write_text("\n".join(lines[:-1]) + "\n")   # a stage-1 run lost
    again = codesign(FEATHER, "chordwise", tmp_path, budget=8, plan=plan, resume=True)
    assert again["two_stage"]["stage1"] == report["two_stage"]["stage1"]
    assert len(log.read_text().splitlines()) == 1 + 2
    log.write_text(log.read_text() + log.read_text().splitlines()[1] + "\n")   # one duplicated
    with pytest.raises(OptimizerError, match="repeats the stage1 k 0"):
        codesign(FEATHER, "chordwise", tmp_path, budget=8, plan=plan, resume=True)
