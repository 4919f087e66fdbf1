"""Results are written before post-processing: a figure or comparison that fails afterwards is a
one-line warning, and the measured results are on disk."""
import json

import pytest
from optimizer_testing import FEATHER, PLAN, SPACE

from featherstar.app import main
from featherstar.optimizer.postprocess import PostProcessingWarning
from featherstar.optimizer.study import run_study


def _broken(*args, **kwargs):
    raise RuntimeError("the plotting backend broke")


def test_a_study_whose_comparison_breaks_keeps_its_summary(tmp_path):
    with pytest.warns(PostProcessingWarning, match="comparison with other-study"):
        summary = run_study(FEATHER, SPACE, tmp_path, iterations=5, plan=PLAN,
                            compare=({"label": "other-study"},))   # a summary without its numbers
    assert json.loads((tmp_path / "summary.json").read_text())["thrust_ratio"] == summary["thrust_ratio"]
    assert (tmp_path / "fig8_validation.png").stat().st_size > 0   # drawn without the broken comparison


def test_a_study_whose_figures_break_keeps_its_summary(tmp_path, monkeypatch):
    monkeypatch.setattr("featherstar.optimizer.study.progress_figure", _broken)
    with pytest.warns(PostProcessingWarning, match="fig6_progress.png not done.*plotting backend broke"):
        run_study(FEATHER, SPACE, tmp_path, iterations=5, plan=PLAN)
    assert "best_params" in json.loads((tmp_path / "summary.json").read_text())


def test_a_sweep_whose_figure_breaks_keeps_its_tables_with_one_warning_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("featherstar.optimizer.cli.sweep_figure", _broken)
    out = tmp_path / "sweep"
    assert main(["sweep", "synthetic:plain", "--family", "spanwise", "--workers", "1", "--no-progress",
                 "--out", str(out)]) == 0
    for name in ("runs.jsonl", "runs.csv", "table.csv", "summary.json"):
        assert (out / name).stat().st_size > 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert warnings == ["featherstar sweep: warning: fig3_sweep.png not done (RuntimeError: the plotting backend "
                        "broke); the results before it are written"]


def test_a_paper_report_whose_figures_break_keeps_paper_json(tmp_path, monkeypatch):
    from featherstar.optimizer.paper import paper

    timing = {"workers": 1, "cpu_count": 1, "tasks": 1, "simulated_s": 0.0, "planned_simulated_s": 600.0,
              "full_planned_simulated_s": 12000.0}
    monkeypatch.setattr(paper, "run_experiments",
                        lambda res, out_dir, **kw: ({"study:chordwise-max": {"error": "StepError: boom"}}, timing))
    monkeypatch.setattr("featherstar.optimizer.paper.figures.draw_all", _broken)
    with pytest.warns(PostProcessingWarning, match="the figures not done"):
        report = paper.generate_report(tmp_path, quick=True, progress=False)
    assert json.loads((tmp_path / "paper.json").read_text())["failures"] == {"study:chordwise-max": "StepError: boom"}
    assert "## Failures" in report.read_text()
