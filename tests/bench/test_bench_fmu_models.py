"""bench/fmu_models.py runs end to end in its reduced mode (plain feather only) and writes
the JSON and plot it promises, with finite positive times."""
from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "fmu_models.py"


def _load_bench():
    spec = importlib.util.spec_from_file_location("bench_fmu_models", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _positive(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0


def test_fmu_models_bench_reduced_mode(tmp_path, monkeypatch):
    # Anything the script takes from the user's cache must come from a private one.
    monkeypatch.setenv("FEATHERSTAR_CACHE", str(tmp_path / "user-cache"))
    bench = _load_bench()
    out = tmp_path / "results"
    assert bench.main(["--quick", "--models", "feather-plain", "--out", str(out)]) == 0
    assert (out / "fmu_models.png").stat().st_size > 0
    result = json.loads((out / "fmu_models.json").read_text())
    assert {"settings", "machine", "notes", "build", "step_cost", "stroke_runs", "total_wall_s"} <= set(result)
    assert result["settings"]["models"] == ["feather-plain"]

    build = result["build"]["feather-plain"]
    assert _positive(build["cold_s"]) and _positive(build["cached_s"])
    assert build["cached_s"] < build["cold_s"]

    cost = result["step_cost"]["feather-plain"]
    for value in (cost["cs_rest"]["do_step_us"], cost["cs_stroke"]["do_step_us"],
                  cost["me"]["derivative_us"], cost["me"]["python_call_overhead_us"]):
        assert _positive(value)

    assert list(result["stroke_runs"]) == ["feather-plain"]
    run = result["stroke_runs"]["feather-plain"]
    for key in ("cs_fmu", "me_fmu", "casadi"):
        assert _positive(run[key]["wall_s"]) and _positive(run[key]["wall_ratio_to_casadi"])
        # Symmetric stroke, plain feather: no net thrust direction.
        assert run[key]["thrust_ratio"] == pytest.approx(1.0, abs=0.1)
    for key in ("cs_fmu", "me_fmu"):
        assert math.isfinite(run[key]["max_abs_thrust_diff_vs_casadi_N"])
        assert run[key]["max_abs_thrust_diff_vs_casadi_N"] < 0.1 * run[key]["max_abs_thrust_casadi_N"]
