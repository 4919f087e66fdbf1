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
