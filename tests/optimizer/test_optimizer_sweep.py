import json
import math
import sys

import pytest
from optimizer_testing import FEATHER, FailingForWideFeathers, always_failing

from featherstar.optimizer.errors import OptimizerError
from featherstar.optimizer.executor import ProcessExecutor, make_executor
from featherstar.optimizer.sweep import (
    L_ROOT_M, PAPER_CONTROLLERS, W_SPINE_M, Controller, format_table, paper_geometries, run_sweep, tabulate,
)

TWO_CONTROLLERS = (Controller(0.5, 0.5, 0.5), Controller(0.5, 1.0, 1.0))


def test_paper_grid():
    chordwise = paper_geometries("chordwise")
    spanwise = paper_geometries("spanwise")
    assert [round(g.width_m * 1000) for g in chordwise[:-1]] == list(range(15, 121, 5))
    assert {g.length_m for g in chordwise[:-1]} == {0.120}
    assert [round(g.length_m * 1000) for g in spanwise[:-1]] == list(range(60, 181, 10))
    assert chordwise[-1].reference and chordwise[-1].width_m == W_SPINE_M
    assert spanwise[-1].reference and spanwise[-1].length_m == L_ROOT_M
    assert chordwise[-1].overrides()["feather.morphology"] == "plain"
    assert chordwise[11].overrides()["feather.width_ratio"] == pytest.approx(7.0)
    assert len(PAPER_CONTROLLERS) == 12
    assert {(c.t_up_s, c.t_down_s, c.t_hold_s) for c in PAPER_CONTROLLERS} == {
        (u, d, h) for u in (0.1, 0.5) for d in (0.5, 1.0) for h in (0.0, 0.5, 1.0)
    }
    with pytest.raises(OptimizerError, match="unknown sweep family 'radial'"):
        paper_geometries("radial")


def test_local_parallel_sweep_tabulates_per_geometry():
    with ProcessExecutor(2) as executor:
        result = run_sweep(FEATHER, ["spanwise"], controllers=TWO_CONTROLLERS, executor=executor, progress=False)
    assert [r["index"] for r in result.runs] == list(range(14 * 2))
    assert len(result.table) == 13 and result.workers == 2
    assert result.simulation_s > 0
    best = max(result.table, key=lambda r: r["thrust_ratio"])
    assert best["ratio"] == pytest.approx(2.0, abs=0.1)  # the synthetic feather's spanwise optimum
    assert "spanwise" in format_table(result.table)


def test_a_failing_run_is_recorded_not_fatal():
    result = run_sweep(FailingForWideFeathers(), ["chordwise"], controllers=TWO_CONTROLLERS[:1], progress=False)
    failed = [r for r in result.runs if r["error"]]
    assert len(failed) == 4 and all("solver failure" in r["error"] for r in failed)
    assert sum(r["failed_runs"] for r in result.table) == 4
    with pytest.raises(OptimizerError, match="every sweep run failed.*no master here"):
        run_sweep(always_failing, ["spanwise"], controllers=TWO_CONTROLLERS[:1], executor=make_executor(workers=1),
                  progress=False)


def test_dask_requested_but_missing_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # makes the import fail
    with pytest.raises(OptimizerError, match=r"tcp://scheduler:8786.*pip install 'featherstar\[dask\]'"):
        make_executor("tcp://scheduler:8786")


def test_normalized_thrust_is_relative_to_the_reference_under_the_same_controller():
    def row(width_m, reference, up, thrust, tr=2.0):
        return {"family": "chordwise", "width_m": width_m, "length_m": 0.12, "ratio": width_m / W_SPINE_M,
                "reference": reference, "t_up_s": up, "t_down_s": 1.0, "t_hold_s": 0.0,
                "thrust_ratio": tr, "mean_thrust_N": thrust, "error": ""}

    runs = [row(0.01, True, 0.1, 0.004), row(0.01, True, 0.5, 0.0), row(0.05, False, 0.1, 0.010, 1.5),
            row(0.05, False, 0.5, 0.030, 2.5)]
    (entry,) = tabulate(runs)
    assert entry["normalized_thrust"] == pytest.approx(2.5)  # 10/4; the zero-thrust reference is skipped
    assert entry["thrust_ratio"] == 2.5 and entry["best_controller"] == "0.5/1.0/0.0"
    (lonely,) = tabulate(runs[2:])
    assert math.isnan(lonely["normalized_thrust"])


def test_resume_runs_only_what_the_log_lacks(tmp_path):
    log = tmp_path / "runs.jsonl"
    full = run_sweep(FEATHER, ["spanwise"], controllers=TWO_CONTROLLERS, executor=make_executor(workers=1),
                     log_path=log, context={"scene": "synthetic"}, progress=False)
    lines = log.read_text().splitlines(keepends=True)
    log.write_text("".join(lines[:6]) + lines[6][:20])  # header, 5 runs, and a record cut by a hard kill
    with pytest.warns(UserWarning, match="dropping an incomplete last record"):
        resumed = run_sweep(FEATHER, ["spanwise"], controllers=TWO_CONTROLLERS, executor=make_executor(workers=1),
                            log_path=log, resume=True, context={"scene": "synthetic"}, progress=False)
    assert resumed.resumed_runs == 5
    assert [{k: v for k, v in r.items() if k != "sim_wall_s"} for r in resumed.runs] == \
           [{k: v for k, v in r.items() if k != "sim_wall_s"} for r in full.runs]
    indices = [json.loads(line)["index"] for line in log.read_text().splitlines()[1:]]
    assert sorted(indices) == list(range(28))  # nothing run twice
    with pytest.raises(OptimizerError, match="already holds a run"):
        run_sweep(FEATHER, ["spanwise"], controllers=TWO_CONTROLLERS, log_path=log, progress=False)
    with pytest.raises(OptimizerError, match="different setup"):
        run_sweep(FEATHER, ["spanwise"], controllers=TWO_CONTROLLERS, log_path=log, resume=True,
                  context={"scene": "testbed"}, progress=False)
