"""Algebraic loops: solved by Newton iteration where possible, a clear error where not."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import make_scene
from featherstar.cosim.errors import StepError
from featherstar.cosim.swimmer.run import run_scene
from test_scene import LOOP

# y1 = 0.5 y2 + 1, y2 = -2 y1 + 3  =>  y1 = 1.25, y2 = 0.5
EXPECTED = {"g1.y": 1.25, "g2.y": 0.5}

FMU_LOOP = {
    "name": "fmu-loop",
    "connections": ["g1.y -> g2.u", "g2.y -> g1.u"],
    "master": {"t_end_s": 0.2, "output_interval_s": 0.01, "step_s": 0.01},
    "blocks": {
        "g1": {"kind": "fmu", "model": "toys:gain", "parameters": {"gain": 0.5, "offset": 1.0}},
        "g2": {"kind": "fmu", "model": "toys:gain", "parameters": {"gain": -2.0, "offset": 3.0}},
        "rec": {"kind": "recorder", "signals": ["g1.y", "g2.y"]},
    },
}


@pytest.mark.parametrize("coupling", ["strong", "jacobi", "gauss-seidel"])
@pytest.mark.parametrize("base", [LOOP, FMU_LOOP], ids=["python-gains", "fmu-gains"])
def test_solvable_loop_is_iterated(base, coupling):
    result = run_scene(make_scene(base, master={"coupling": coupling}))
    for name, value in EXPECTED.items():
        assert np.allclose(result[name], value, rtol=0, atol=1e-9), name
    loops = result.info["loops"]
    assert len(loops) == 1 and loops[0]["solves"] > 0
    assert loops[0]["loop"] == "g1.y -> g2.u -> g2.y -> g1.u -> g1.y"
    # a linear loop: Newton converges in one iteration per solve (plus the warm-started ones)
    assert loops[0]["iterations"] <= loops[0]["solves"]


def test_singular_loop_stops_with_the_loop_named():
    scene = make_scene(LOOP, blocks={"g2": {"kind": "gain", "gain": 2.0, "offset": 3.0}})  # loop gain 0.5*2 = 1
    with pytest.raises(StepError) as err:
        run_scene(scene)
    text = str(err.value)
    assert "algebraic loop g1.y -> g2.u -> g2.y -> g1.u -> g1.y has no unique solution" in text
    assert err.value.t_s == 0.0
