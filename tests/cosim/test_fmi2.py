"""Any standard FMU, not only ours: a hand-written FMI 2.0 FMU (tests/cosim/fmi2_lag) compiled
here, used as a scene block by file, in strong (ME) and weak (CS) coupling, with rollback."""
from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from featherstar.cosim.scene.data import scene_from_dict
from featherstar.cosim.scene.graph import plan
from featherstar.cosim.swimmer.run import run_scene
from featherstar.cosim.swimmer.stroke import Stroke, root_motion
from lag_fmu import build_lag_fmu
from scipy.integrate import solve_ivp


@pytest.fixture(scope="module")
def lag_fmu(tmp_path_factory) -> Path:
    if shutil.which("gcc") is None:
        pytest.skip("gcc is needed to build the FMI 2.0 test FMU")
    return build_lag_fmu(tmp_path_factory.mktemp("fmi2"))


def _scene(fmu: Path, coupling: str, **master):
    return scene_from_dict({
        "name": "fmi2",
        "connections": ["controller.angle_rad -> lag.u", "lag.z -> lag2.u"],
        "master": {"coupling": coupling, "t_end_s": 3.0, "output_interval_s": 0.005, "step_s": 0.005,
                   "rtol": 1e-9, "atol": 1e-11, **master},
        "blocks": {
            "controller": {"kind": "stroke"},
            "lag": {"kind": "fmu", "fmu": str(fmu), "parameters": {"tau": 0.2, "k": 0.5}},
            "lag2": {"kind": "fmu", "fmu": str(fmu), "parameters": {"tau": 0.05}},
            "rec": {"kind": "recorder", "signals": ["lag.x", "lag.z", "lag2.x"]},
        },
    })


def _exact(t_end: float) -> tuple[np.ndarray, np.ndarray]:
    stroke = Stroke()

    def f(t, x):
        u = root_motion(stroke, t)[0]
        return [(u - x[0]) / 0.2, (0.5 * u - x[1]) / 0.05]

    t = np.linspace(0, t_end, 601)
    sol = solve_ivp(f, (0, t_end), [0.0, 0.0], t_eval=t, rtol=1e-11, atol=1e-13, max_step=0.01)
    return t, sol.y


def test_fmi2_ports_units_and_feedthrough_are_read(lag_fmu):
    p = plan(_scene(lag_fmu, "strong"))
    rb = p.blocks["lag"]
    assert rb.fmu_info.fmi_version == "2.0"
    assert rb.inputs["u"].unit == "rad" and rb.outputs["x"].depends_on == () and rb.outputs["z"].depends_on == ("u",)
    assert set(rb.fmu_info.parameters) == {"tau", "k"}


@pytest.mark.parametrize("coupling", ["strong", "jacobi", "gauss-seidel"])
def test_fmi2_fmu_runs_in_every_coupling(lag_fmu, coupling):
    result = run_scene(_scene(lag_fmu, coupling))
    t, (x1, x2) = _exact(3.0)
    e1 = np.max(np.abs(np.interp(t, result.time, result["lag.x"]) - x1))
    e2 = np.max(np.abs(np.interp(t, result.time, result["lag2.x"]) - x2))
    if coupling == "strong":
        assert e1 < 1e-7 and e2 < 1e-7
    else:  # zero-order hold at 5 ms
        assert e1 < 2e-2 and e2 < 2e-2


def test_fmi2_adaptive_rollback(lag_fmu):
    result = run_scene(_scene(lag_fmu, "jacobi", adaptive=True, step_s=0.1, macro_rtol=1e-3))
    assert result.summary["stats"]["rejected_steps"] > 0
    t, (x1, _) = _exact(3.0)
    assert np.max(np.abs(np.interp(t, result.time, result["lag.x"]) - x1)) < 2e-2


def test_unknown_fmu_parameter_is_a_scene_error(lag_fmu):
    from featherstar.cosim.errors import SceneError

    bad = _scene(lag_fmu, "strong").with_overrides({"lag.nope": 1.0})
    with pytest.raises(SceneError, match="has no tunable/fixed parameter 'nope'; it has: k, tau"):
        plan(bad)


@pytest.fixture(scope="module")
def ball_fmu(tmp_path_factory) -> Path:
    if shutil.which("gcc") is None:
        pytest.skip("gcc is needed to build the FMI 2.0 test FMU")
    source = Path(__file__).parent / "fmi2_ball"
    work = tmp_path_factory.mktemp("ball")
    include = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(["gcc", "-O2", "-shared", "-fPIC", f"-I{include}", str(source / "ball.c"),
                    "-o", str(work / "ball.so")], check=True)
    fmu = work / "ball.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.write(source / "modelDescription.xml", "modelDescription.xml")
        z.write(work / "ball.so", "binaries/linux64/ball.so")
    return fmu


@pytest.mark.parametrize("coupling", ["strong", "jacobi"])
def test_state_events_of_a_generic_me_fmu(ball_fmu, coupling):
    """Bouncing ball (FMI 2.0 ME only, one event indicator): CVODE's root finding locates each
    bounce and the event iteration applies v := -e v; bounce times are analytic."""
    scene = scene_from_dict({
        "name": "ball", "connections": [],
        "master": {"coupling": coupling, "t_end_s": 2.5, "output_interval_s": 0.001, "step_s": 0.01,
                   "rtol": 1e-10, "atol": 1e-12},
        "blocks": {"ball": {"kind": "fmu", "fmu": str(ball_fmu)},
                   "rec": {"kind": "recorder", "signals": ["ball.h", "ball.v", "ball.bounces"]}},
    })
    result = run_scene(scene)
    g, e = 9.81, 0.7
    t1 = np.sqrt(2 / g)
    bounce_times = [t1, t1 + 2 * e * g * t1 / g, t1 + 2 * e * g * t1 / g + 2 * e * e * g * t1 / g]
    for k, tb in enumerate(bounce_times, start=1):  # the count steps up at each bounce, not before
        before = result["ball.bounces"][np.searchsorted(result.time, tb - 0.011)]
        after = result["ball.bounces"][np.searchsorted(result.time, tb + 0.011)]
        assert (before, after) == (k - 1, k)
    assert np.min(result["ball.h"]) > -1e-6
    # the apex after the first bounce: e² h0
    flight = (result.time > t1) & (result.time < bounce_times[1])
    assert np.max(result["ball.h"][flight]) == pytest.approx(e * e * 1.0, rel=1e-3)
