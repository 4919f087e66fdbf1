"""`featherstar paper`: the report's core at a tiny resolution, and its pieces without a master.

The end-to-end test runs every experiment of the report (studies, symmetric-stroke runs, sweep, robot)
through the real FMU master at the smallest resolution that still exercises each path, then checks
that every figure is drawn and linked, that the claims table has every row, and that the numbers
the table and paper.json report are finite.
"""
import argparse
import dataclasses
import json
import math

import pytest
from featherstar.optimizer.cli import register
from featherstar.optimizer.objective import master_available
from featherstar.optimizer.paper.figures import draw_all
from featherstar.cosim.jsonable import json_safe
from featherstar.optimizer.paper.paper import (
    FULL,
    QUICK,
    collect,
    generate_report,
    run_experiments,
    study_specs,
    sweep_geometries,
)
from featherstar.optimizer.paper.family import validated_stroke_task
from featherstar.optimizer.paper.plan import MORPHOLOGIES, PERIOD_S, Member
from featherstar.optimizer.paper.report import claims, write_markdown
from featherstar.optimizer.paper.robustness import AGREES, DISAGREES, UNDECIDED, family_table
from featherstar.optimizer.space import stroke_overrides, symmetric_stroke
from featherstar.optimizer.study import BEST_VALIDATION_INDEX
from featherstar.optimizer.sweep import Controller

TINY = dataclasses.replace(
    QUICK, name="test", sweep_geometries=1, sweep_controllers=(Controller(0.5, 1.0, 0.0),), sweep_settle_periods=0,
    sweep_periods=1, settle_periods=0, periods=1, iterations=2, initial_points=2, fig7_iterations=2,
    validation_repeats=2, validation_periods=1, robot_periods=1, robot_settle_periods=0, workers=2,
    family=("wake-self", "hinge-1e-3"), reoptimize=("plain-max",),   # a wake law; a member the plain feather lacks
)
FIGURES = ["fig3_sweep.png", "fig5_symmetric.png", "fig5_plain_run.png", "fig5_chordwise_run.png",
           "fig5_spanwise_run.png", "fig6_chordwise.png", "fig6_spanwise.png", "fig7_strokes.png",
           "fig8_validation.png", "fig9_robot.png"]
CLAIMS = ["plain_symmetric", "chordwise_symmetric", "spanwise_symmetric", "chordwise_optimized", "spanwise_optimized",
          "plain_optimized", "useful_thrust", "flapped_best", "flapped_worst", "robot_chordwise", "robot_plain",
          "robot_best_worst"]


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    if not master_available():
        pytest.skip("featherstar.cosim.run_scene (the FMU master) is not available")
    return generate_report(tmp_path_factory.mktemp("paper"), quick=True, progress=False, resolution=TINY)


def test_every_figure_is_drawn_and_linked(report):
    text = report.read_text()
    for name in FIGURES:
        assert (report.parent / name).stat().st_size > 4_000, name
        assert f"({name})" in text, f"{name} is not linked from report.md"
    assert "## How to read this" in text and "Run time:" in text and "## Resolution" in text


def test_the_table_holds_every_claim_with_a_finite_simulated_value(report):
    data = json.loads((report.parent / "paper.json").read_text())
    assert data["failures"] == {}
    assert [row["id"] for row in data["claims"]] == CLAIMS
    text = report.read_text()
    for i, row in enumerate(data["claims"], 1):
        assert isinstance(row["simulated"], float) and math.isfinite(row["simulated"]), row
        assert row["agrees"] in (True, False)
        assert f"| {i} | {row['claim']} |" in text


def test_every_claim_carries_its_range_across_the_model_family(report):
    data = json.loads((report.parent / "paper.json").read_text())
    assert [m["name"] for m in data["family_members"]] == list(TINY.family)
    text = report.read_text()
    assert "model family: range (ends)" in text and "## Model-form uncertainty" in text
    for row in data["claims"]:
        assert set(row["family"]) == {"default", *TINY.family}, row["id"]
        assert row["robust"] in (AGREES, DISAGREES, UNDECIDED) and row["range_meaning"]
        lo, hi = row["range"]
        assert all(isinstance(v, float) and math.isfinite(v) for v in row["family"].values()), row
        assert row["family"][row["range_ends"][0]] == lo <= row["simulated"] <= hi == row["family"][row["range_ends"][1]]
    plain = next(row for row in data["claims"] if row["id"] == "plain_optimized")
    reoptimized = data["family"]["wake-self"]["studies"]["plain-max"]
    assert plain["family"]["wake-self"] == reoptimized["summary"]["thrust_ratio"] and "evaluations" in reoptimized
    assert plain["family"]["hinge-1e-3"] == plain["simulated"]     # no hinge on the plain feather


def test_the_family_measures_the_default_model_exactly_as_the_report_does(report):
    """Under no overrides the family's measurement of a stroke reproduces the default's own numbers
    (the same run, sets and noise): a member's value differs from the default's by its model only."""
    data = json.loads((report.parent / "paper.json").read_text())
    default = Member("default", (), "the default model")
    study = data["studies"]["chordwise-max"]
    again = validated_stroke_task("chordwise", 7.5, PERIOD_S, study["best_overrides"], default, TINY,
                                  BEST_VALIDATION_INDEX)
    assert again["thrust_ratio"] == study["summary"]["thrust_ratio"]
    symmetric = validated_stroke_task("plain", None, PERIOD_S, stroke_overrides(symmetric_stroke(PERIOD_S)), default,
                                      TINY, (100 + MORPHOLOGIES.index("plain"),))
    assert symmetric["thrust_ratio"] == pytest.approx(data["symmetric"]["plain"]["thrust_ratio"], rel=1e-9)


def test_paper_json_numbers_are_finite(report):
    data = json.loads((report.parent / "paper.json").read_text())
    numbers = [data["timing"]["total_wall_s"], data["timing"]["simulated_s"]]
    numbers += [run[key] for run in data["symmetric"].values() for key in ("thrust_ratio", "mean_thrust_N")]
    numbers += [study["estimated_thrust_ratio"] for study in data["studies"].values()]
    numbers += [study["summary"][key] for study in data["studies"].values() if "summary" in study
                for key in ("thrust_ratio", "baseline_thrust_ratio", "mean_thrust_N")]
    numbers += [run["mean_speed_m_s"] for run in data["robot"].values()]
    numbers += [row["thrust_ratio"] for row in data["sweep"]["table"]]
    assert len(data["studies"]) == 8 and len(data["robot"]) == 9 and len(data["sweep"]["table"]) == 2
    assert all(isinstance(x, float) and math.isfinite(x) for x in numbers), numbers


def test_failed_experiments_still_give_a_report(tmp_path):
    """Every task failed: the figures say so, the table says n/a, the failures are listed."""
    data = collect({"study:chordwise-max": {"error": "StepError: boom"}, "fig5:plain": {"error": "x"}})
    table = claims(data)
    assert [row["id"] for row in table] == CLAIMS and all(row["agrees"] is None for row in table)
    figures = draw_all(data, QUICK, tmp_path)
    timing = {"total_wall_s": 1.0, "workers": 1, "cpu_count": 1, "tasks": 2, "simulated_s": 0.0,
              "planned_simulated_s": 600.0, "full_planned_simulated_s": 12000.0}
    text = write_markdown(tmp_path / "report.md", data, table, figures, QUICK, timing).read_text()
    assert "## Failures" in text and "StepError: boom" in text and "n/a" in text


def test_resolutions_plan_the_paper_experiments():
    assert [round(g.ratio, 2) for g in sweep_geometries("chordwise", 4)] == [1.5, 5.5, 7.5, 9.5, 1.0]
    assert len(sweep_geometries("spanwise", None)) == 14 and sweep_geometries("spanwise", None)[-1].reference
    quick, full = study_specs(QUICK), study_specs(FULL)
    assert sorted(quick) == sorted(["plain-max", "plain-min", "chordwise-max", "chordwise-min", "spanwise-max",
                                    "spanwise-min", "chordwise-7.5-3s", "spanwise-2-3s"])
    assert len(full) == 6 + 2 * 3 * 2 - 2  # Fig. 7's WR 7.5 / LR 2 at 1.5 s are the Fig. 6 studies


def test_cli_registers_paper():
    parser = argparse.ArgumentParser()
    register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["paper", "--quick", "--out", "somewhere", "--workers", "1"])
    assert args.func.__name__ == "_paper_command" and args.quick and args.workers == 1


def test_a_resumed_report_runs_only_the_missing_experiments_to_the_same_numbers(report, tmp_path):
    """Experiments lost from tasks.jsonl (a kill): --resume runs those and reproduces the claims."""
    log = report.parent / "tasks.jsonl"
    lines = log.read_bytes().splitlines(keepends=True)
    labels = [json.loads(line)["label"] for line in lines[1:]]
    # a logged study's robot run and its optimum's runs under the model family must be queued again
    lost = {"robot:chordwise-best", "sweep:0", "family:wake-self:eval:chordwise-max",
            "family:hinge-1e-3:robot:spanwise-worst", "family:wake-self:study:plain-max"}
    assert lost <= set(labels)
    (tmp_path / "tasks.jsonl").write_bytes(b"".join(line for line, label in zip(lines, [None, *labels])
                                                   if label not in lost))
    results, _ = run_experiments(TINY, tmp_path, progress=False, resume=True)   # the figures are not the point
    after = [json.loads(line)["label"] for line in (tmp_path / "tasks.jsonl").read_text().splitlines()[1:]]
    assert sorted(after) == sorted(labels) and after[: len(labels) - len(lost)] == [l for l in labels if l not in lost]
    original = {row["id"]: row["family"] for row in json.loads((report.parent / "paper.json").read_text())["claims"]}
    data = collect(results)
    table = family_table(data, claims(data), TINY, claims)
    again = {row["id"]: row["family"] for row in json.loads(json.dumps(json_safe(table)))}
    assert again == original
    with pytest.raises(Exception, match="already holds a run"):
        run_experiments(TINY, tmp_path, progress=False)
