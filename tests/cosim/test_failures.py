"""A blow-up stops with the block, the time and the likely cause; what was computed is kept."""
from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import OSCILLATOR, make_scene
from featherstar.cosim.errors import StepError
from featherstar.cosim.swimmer.run import run_scene

from featherstar.app import main

POISONED = dict(
    connections=["a.position_m -> b.other_position_m", "a.velocity_m_s -> b.other_velocity_m_s",
                 "b.force_N -> poison.u", "poison.y -> a.force_N"],
    blocks={"poison": {"kind": "python", "factory": "toy_blocks:Poison", "parameters": {"t_bad": 0.5}}},
    master={"rtol": 1e-6, "atol": 1e-8},
)


@pytest.mark.parametrize("coupling", ["strong", "jacobi", "gauss-seidel"])
def test_nan_names_the_block_and_time_and_keeps_partial_results(coupling):
    scene = make_scene(OSCILLATOR, **POISONED)
    with pytest.raises(StepError) as err:
        run_scene(scene, {"master.coupling": coupling})
    exc = err.value
    assert exc.block == "poison"  # the origin, not the blocks the NaN flowed into
    assert 0.5 - 2e-3 <= exc.t_s <= 0.52
    assert "nan" in str(exc).lower() and "likely cause" in str(exc)
    partial = exc.partial
    assert partial is not None and not partial.complete
    assert partial.time[-1] < 0.5 + 1e-9 and partial.time[-1] > 0.45
    assert np.all(np.isfinite(partial["a.position_m"]))
    assert partial.summary["failed_block"] == "poison"


BLOWUP = {
    "name": "blowup",
    "connections": ["zero.u -> x.u"],
    "master": {"t_end_s": 2.0, "output_interval_s": 0.01},
    "blocks": {
        "x": {"kind": "fmu", "model": "toys:blowup"},
        "zero": {"kind": "constant", "outputs": {"u": {"value": 0.0, "unit": "1"}}},
        "rec": {"kind": "recorder", "signals": ["x.y"]},
    },
}


def test_solver_failure_on_finite_time_blowup():
    with pytest.raises(StepError) as err:
        run_scene(make_scene(BLOWUP))  # x' = x², x(0) = 1: x -> inf at t = 1
    exc = err.value
    assert exc.block == "x" and 0.9 < exc.t_s <= 1.0 + 1e-6
    assert "blow-up" in str(exc) or "inf" in str(exc).lower()
    assert exc.partial.time[-1] <= 1.0 and exc.partial.time[-1] > 0.9


def test_weak_coupling_blowup_reports_fmu_block():
    with pytest.raises(StepError) as err:
        run_scene(make_scene(BLOWUP, master={"coupling": "jacobi", "step_s": 0.01}))
    exc = err.value
    assert exc.block == "x" and 0.9 < exc.t_s <= 1.0 + 1e-6
    assert exc.partial is not None and len(exc.partial.time) > 50


def test_cli_keeps_partial_results_and_exits_2(tmp_path, capsys, monkeypatch):
    path = tmp_path / "blowup.toml"
    path.write_text("""
name = "blowup"
connections = ["zero.u -> x.u"]
[master]
t_end_s = 2.0
output_interval_s = 0.01
[blocks.x]
kind = "fmu"
model = "toys:blowup"
[blocks.zero]
kind = "constant"
outputs = { u = { value = 0.0, unit = "1" } }
[blocks.rec]
kind = "recorder"
signals = ["x.y"]
""")
    rc = main(["run", str(path), "--out", str(tmp_path / "out"), "-q"])
    assert rc == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("featherstar: error")]
    assert len(lines) == 1 and "block 'x' at t=" in lines[0]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["complete"] is False and summary["failed_block"] == "x"
    assert (tmp_path / "out" / "results.csv").read_text().count("\n") > 50
