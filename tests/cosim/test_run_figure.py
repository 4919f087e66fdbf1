"""The run figure carries its run's validity and is readable: rendered and inspected (titles,
labels with units, non-empty panels, legends with their artists, integer period ticks)."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from featherstar.cosim.swimmer.run import run_scene
from featherstar.cosim.swimmer.run_figure import run_figure


@pytest.fixture(scope="module")
def plain_run():
    return run_scene("testbed", {"feather.morphology": "plain", "master.periods": 5, "metrics.settle_periods": 2})


def _texts(fig) -> str:
    return " ".join([fig._suptitle.get_text()] + [a.get_ylabel() + " " + a.get_xlabel() for a in fig.axes])


def _assert_readable(fig) -> None:
    for ax in fig.axes:
        has_content = ax.lines or ax.patches or ax.collections or ax.texts
        assert has_content, f"empty panel: {ax.get_ylabel()!r}"
        assert ax.get_ylabel(), "a panel without a y label"
        legend = ax.get_legend()
        if legend is not None:
            assert all(h is not None for h in legend.legend_handles)
            assert all(t.get_text() for t in legend.get_texts())


def test_a_complete_run_names_scene_and_morphology_and_shows_its_window(plain_run):
    fig = run_figure(plain_run)
    title = fig._suptitle.get_text()
    assert title.startswith("testbed (plain feather): TR = ") and "INCOMPLETE" not in title
    _assert_readable(fig)
    legend = fig.axes[0].get_legend()
    assert "metric window" in [t.get_text() for t in legend.get_texts()]
    assert all(float(tick).is_integer() for tick in fig.axes[2].get_xticks())
    assert "mN" in _texts(fig) and "(s)" in _texts(fig)


def test_an_incomplete_run_says_so_first_and_marks_its_excluded_periods(plain_run):
    """As a hardware run with periods 2 and 3 excluded and too few valid ones."""
    run = copy.copy(plain_run)
    run.summary = copy.deepcopy(plain_run.summary)
    run.complete = False
    a = run.summary["window_s"][0]
    period = run.summary["period_s"]
    run.summary["incomplete_reason"] = "valid_periods: 1 of 3 valid (2 needed)"
    run.summary["validity"] = {"valid_periods": 1, "invalid_periods": [
        {"period": 2, "start_s": a + period, "reasons": ["deadline misses"]},
        {"period": 3, "start_s": a + 2 * period, "reasons": ["data gap"]}]}
    fig = run_figure(run)
    assert fig._suptitle.get_text().startswith("INCOMPLETE: valid_periods: 1 of 3 valid")
    assert "(not a result)" in fig._suptitle.get_text()
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert "excluded period" in labels
    bar_labels = [t.get_text() for t in fig.axes[2].get_legend().get_texts()]
    assert "excluded period" in bar_labels
    _assert_readable(fig)


def test_no_valid_period_is_said_in_the_panel_not_left_empty(plain_run):
    run = copy.copy(plain_run)
    run.summary = {k: v for k, v in plain_run.summary.items() if k != "per_period_thrust_ratio"}
    run.summary["validity"] = {"valid_periods": 0, "invalid_periods": [], "reason": "every period missed deadlines"}
    run.complete = False
    fig = run_figure(run)
    texts = [t.get_text() for t in fig.axes[2].texts]
    assert any("every period missed deadlines" in t for t in texts)
    _assert_readable(fig)


def test_a_start_transient_does_not_squash_the_thrust_axis(plain_run):
    run = copy.copy(plain_run)
    run.signals = dict(plain_run.signals)
    thrust = np.array(run.signals[run.scene.metrics.thrust])
    thrust[:5] = 50.0   # a 50 N spike at the start
    run.signals[run.scene.metrics.thrust] = thrust
    fig = run_figure(run)
    low, high = fig.axes[0].get_ylim()
    assert high < 1e3 * 50.0 / 10 and "clipped" in fig.axes[0].get_ylabel()


def test_the_console_summary_of_an_incomplete_run_leads_with_it(plain_run):
    from featherstar.cosim.swimmer.report import summary_table

    summary = dict(plain_run.summary, incomplete_reason="valid_periods: 0 of 3 valid")
    assert summary_table(summary).splitlines()[0] == "INCOMPLETE (not a result): valid_periods: 0 of 3 valid"
    assert summary_table(plain_run.summary).splitlines()[0].startswith("scene: ")
