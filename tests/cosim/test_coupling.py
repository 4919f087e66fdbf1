"""Strong and weak coupling against the monolithic CasADi reference, on toy models exported as
FMUs (FMI 3.0, ME + CS), and the weak coupling's order of convergence."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import OSCILLATOR, make_scene
from featherstar.cosim.swimmer.run import run_scene
from featherstar.dashboard.monolithic import run_monolithic


@pytest.fixture(scope="module")
def reference():
    return run_monolithic(make_scene(OSCILLATOR), rtol=1e-11, atol=1e-13)


def _error(result, reference, signal="a.position_m"):
    x = np.interp(reference.time, result.time, result[signal])
    return float(np.max(np.abs(x - reference[signal])))


def test_strong_matches_monolithic(oscillator, reference):
    result = run_scene(oscillator)
    assert result.info["instantiated"] == ["a", "b"]
    for name in ("a.position_m", "b.position_m", "b.force_N"):
        scale = np.max(np.abs(reference[name]))
        assert np.max(np.abs(result[name] - reference[name])) < 1e-7 * max(scale, 1.0), name


def test_casadi_backend_matches_fmu_backend(oscillator, reference):
    result = run_scene(oscillator, {"master.backend": "casadi"})
    assert _error(result, reference) < 1e-7


@pytest.mark.parametrize("coupling", ["jacobi", "gauss-seidel"])
def test_weak_coupling_converges_at_first_order(oscillator, reference, coupling):
    steps = [4e-3, 2e-3, 1e-3, 5e-4]
    errors = [_error(run_scene(oscillator, {"master.coupling": coupling, "master.step_s": h,
                                            "master.rtol": 1e-9, "master.atol": 1e-11}), reference)
              for h in steps]
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    # zero-order hold of the coupling signals: first order in the macro step
    assert 0.85 < slope < 1.25, (slope, errors)
    assert errors[-1] < 0.05


def test_adaptive_macro_step_rolls_back_and_meets_tolerance(oscillator, reference):
    def adaptive(tol):
        return run_scene(oscillator, {"master.coupling": "jacobi", "master.adaptive": True,
                                      "master.step_s": 0.05, "master.macro_rtol": tol})
    loose, tight = adaptive(4e-3), adaptive(1e-3)
    assert tight.summary["stats"]["rejected_steps"] > 0  # the first, far too large step is rolled back
    assert loose.summary["stats"]["macro_steps"] < tight.summary["stats"]["macro_steps"]
    # the error follows the tolerance (first-order control) ...
    assert _error(loose, reference) / _error(tight, reference) > 2.5
    # ... and at macro_rtol 1e-3 matches a fixed 1 ms step on this oscillator (~2 % of amplitude)
    assert _error(tight, reference) < 0.03
    assert np.all(np.diff(tight.time) > 0)


@pytest.mark.parametrize("coupling", ["strong", "gauss-seidel"])
def test_fmu_file_block_matches_model_block(oscillator, reference, coupling, tmp_path):
    """An FMI 3.0 FMU used by path (ports, units and feedthrough read from its XML only)."""
    from featherstar.fmu_src.export import build_fmu
    from toys import oscillator_b

    path = build_fmu(oscillator_b(), tmp_path)
    by_file = make_scene(OSCILLATOR, blocks={"b": {"kind": "fmu", "fmu": str(path)}},
                         master={"coupling": coupling, "step_s": 1e-3})
    by_model = make_scene(OSCILLATOR, master={"coupling": coupling, "step_s": 1e-3})
    a, b = run_scene(by_file), run_scene(by_model)
    assert np.max(np.abs(a["a.position_m"] - b["a.position_m"])) < 1e-9
