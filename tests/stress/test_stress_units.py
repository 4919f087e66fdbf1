"""N from 2 to 40 units: the chain's highest mode grows as N² (17 Hz at N = 5, 1200 Hz at N = 40),
so the ODE gets stiff and each right-hand side more expensive.

FMUs are used where they compile in seconds (N <= 10; a cold build takes 40 s at N = 20 and
~6.5 min at N = 40). Larger N run in-process (`master.backend = casadi`, the same equations on
CasADi's virtual machine: ~0.2 ms per RHS at N = 20, ~1 ms at N = 40, plus ~10 s to build the
N = 40 model symbolically), on runs short enough for the suite's budget. The plain feather is
periodic, so discretisations are compared pointwise: the thrust must converge as N grows.
"""
from __future__ import annotations

import functools

import numpy as np
import pytest

from stress_support import THRUST, assert_physical, run_case

pytestmark = pytest.mark.stress

FULL = {"master.periods": 5, "metrics.settle_periods": 3}


@pytest.mark.parametrize("morphology,n,coupling", [
    ("plain", 2, "strong"),
    ("plain", 5, "strong"),
    ("plain", 5, "jacobi"),
    ("spanwise", 2, "strong"),   # the smallest spanwise chain: one unit each side of the hinge
    ("spanwise", 4, "gauss-seidel"),
])
def test_small_chains_as_fmus(morphology, n, coupling):
    result = run_case("testbed", {"feather.morphology": morphology, "feather.n_units": n,
                                  "master.coupling": coupling, **FULL})
    assert_physical(result, "testbed", morphology)


@functools.lru_cache(maxsize=None)
def _first_stroke(n: int, t_end: float):
    """The plain feather over the start of the first stroke (kinematic scene, strong coupling)."""
    backend = "fmu" if n <= 10 else "casadi"
    method = "adams" if n <= 20 else "bdf"  # N = 40: 1200 Hz chain mode, Adams would be step-limited
    return run_case("kinematic", {"feather.morphology": "plain", "feather.n_units": n, "master.backend": backend,
                                  "master.method": method, "master.t_end_s": t_end, "master.rtol": 1e-7,
                                  "master.atol": 1e-9})


def _difference(a, b) -> float:
    return float(np.max(np.abs(a[THRUST] - np.interp(a.time, b.time, b[THRUST]))) / np.max(np.abs(a[THRUST])))


def test_plain_thrust_converges_with_n_up_to_20():
    runs = {n: _first_stroke(n, 1.5) for n in (5, 10, 20)}
    for run in runs.values():
        assert_physical(run, "kinematic", "plain", whole_periods=False)
    d_coarse, d_fine = _difference(runs[10], runs[5]), _difference(runs[20], runs[10])
    assert d_fine < 0.5 * d_coarse, (d_coarse, d_fine)  # converging, at better than first order
    assert d_fine < 0.1


def test_plain_forty_units_in_process():
    """N = 40 (80 states): only the first 0.1 s fits the budget in-process; it must be physical
    and continue the convergence seen up to N = 20."""
    n40, n20, n10 = (_first_stroke(n, 0.1) for n in (40, 20, 10))
    assert_physical(n40, "kinematic", "plain", whole_periods=False)
    assert _difference(n40, n20) < _difference(n20, n10)


def test_spanwise_twenty_units_in_process():
    result = run_case("kinematic", {"feather.morphology": "spanwise", "feather.n_units": 20,
                                    "master.backend": "casadi", "master.method": "bdf", "master.t_end_s": 0.5})
    assert_physical(result, "kinematic", "spanwise", whole_periods=False)
