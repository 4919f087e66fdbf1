"""bench/peers.py on its smallest system (stroke -> plain feather, 2 periods): featherstar's
couplings and every peer that imports here run on the same FMU files, against the tight
reference; a peer that does not import is reported skipped with its import error."""
from __future__ import annotations

import importlib
import importlib.util
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
PEERS = {"libcosim (libcosimpy)": "libcosimpy", "Ecos (ecospy)": "ecospy", "fmpy simulate_fmu (CS)": "fmpy"}


def _load(name: str):
    sys.path.insert(0, str(BENCH))
    try:
        spec = importlib.util.spec_from_file_location(f"bench_{name}", BENCH / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module   # dataclasses look their module up there
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(BENCH))


def _importable(module: str) -> str | None:
    try:
        importlib.import_module(module)
        return None
    except Exception as exc:  # ImportError, or OSError from a missing shared library
        return f"{type(exc).__name__}: {exc}"


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("peers")
    assert _load("peers").main(["--quick", "--systems", "plain", "--out", str(out)]) == 0
    assert (out / "peers.png").stat().st_size > 0
    return json.loads((out / "peers.json").read_text())


def _rows(result) -> dict[str, dict]:
    return {row["run"]: row for row in result["systems"]["plain"]["rows"]}


def test_strong_is_far_nearer_the_reference_than_every_co_simulation(result):
    rows = _rows(result)
    strong = rows["featherstar strong"]
    assert strong["status"] == "ok" and strong["wall_over_featherstar_strong"] == 1.0
    # measured: strong TR 3e-7, mean thrust 2e-5 off; the 1 ms co-simulations 3.5e-5 to 5e-5 and 2e-3
    assert strong["tr_rel_error"] < 1e-5 and strong["mean_thrust_rel_error"] < 1e-3
    cosim = [r for r in rows.values() if r["status"] == "ok" and r["coupling"] != "strong"]
    assert {"featherstar jacobi", "featherstar gauss-seidel"} <= {r["run"] for r in cosim}
    for row in cosim:
        for key in ("tr_rel_error", "mean_thrust_rel_error", "max_thrust_error_rel_peak",
                    "first_period_thrust_error_rel_peak"):
            assert math.isfinite(row[key]) and 10 * strong[key] < row[key], (row["run"], key)
        assert row["wall_s"] > 0 and math.isfinite(row["wall_over_featherstar_strong"])
        assert row["cpu_s"] > 0 and math.isfinite(row["cpu_over_featherstar_strong"])


@pytest.mark.parametrize("label", list(PEERS))
def test_each_peer_runs_or_says_why_not(result, label):
    row = _rows(result)[label]
    reason = _importable(PEERS[label])
    if reason is not None:
        assert row["status"] == "skipped" and PEERS[label] in row["reason"]
        pytest.skip(f"{PEERS[label]} not importable here: {reason}")
    assert row["status"] == "ok", row
    jacobi = _rows(result)["featherstar jacobi"]
    # A fixed-step master on the same FMUs at the same step: the same error, within a factor 2.
    assert 0.5 < row["tr_rel_error"] / jacobi["tr_rel_error"] < 2
    assert row["max_thrust_error_rel_peak"] < 0.05


def test_ecos_and_featherstar_jacobi_compute_the_same_numbers(result):
    if _importable("ecospy"):
        pytest.skip("ecospy not importable here")
    rows = _rows(result)
    for key in ("thrust_ratio", "mean_thrust_N"):
        assert rows["Ecos (ecospy)"][key] == pytest.approx(rows["featherstar jacobi"][key], rel=1e-9)


def test_the_readme_table_comes_from_the_json(result):
    table = result["readme_table_md"]
    for row in _rows(result).values():
        assert f"| {row['run']} | {row['coupling']} |" in table
        if row["status"] == "ok":
            assert f"{row['wall_over_featherstar_strong']:.2f}x | {row['cpu_over_featherstar_strong']:.2f}x |" in table


def test_a_peer_that_does_not_import_is_skipped_with_its_error(monkeypatch):
    masters = _load("_peer_masters")
    real = importlib.import_module

    def fake(name, *args):
        if name == "ecospy":
            raise OSError("libtbb.so.12: cannot open shared object file")
        return real(name, *args)

    monkeypatch.setattr(masters.importlib, "import_module", fake)
    reasons = masters.available()
    assert reasons["ecos"] == "ecospy does not import: OSError: libtbb.so.12: cannot open shared object file"
    report = _load("_peers_report")
    table = report.markdown_table({
        "settings": {"reference_rtol": 1e-10, "step_s": 1e-3, "rtol": 1e-6, "repeats": 1},
        "systems": {"plain": {"description": "d", "periods": 2, "metric_window_s": [1.5, 3.0],
                              "rows": [{"run": "Ecos (ecospy)", "coupling": "fixed-step", "status": "skipped",
                                        "reason": reasons["ecos"]}]}}})
    assert "| Ecos (ecospy) | fixed-step | skipped: ecospy does not import: OSError: libtbb.so.12" in table


def test_bit_identical_groups():
    peers = _load("peers")
    a = np.array([1.0, 2.0])
    groups = peers.identical_records({"x": a, "y": a.copy(), "z": a + np.array([0.0, 1e-12])})
    assert groups == [["x", "y"]]


def test_the_servo_fmu_fmi_3_and_2_in_every_master_each_in_its_own_process(tmp_path):
    """A master that dies on an FMU (measured: libcosim 0.11 of libcosimpy 0.0.6 gets SIGSEGV on
    every FMI 3.0 FMU) is reported as that crash; the bench itself goes on."""
    compat = _load("_fmu_compat")
    matrix = compat.compat_matrix(tmp_path, ["servo"], log=lambda line: None)["servo"]
    for version in ("fmi3", "fmi2"):
        entry = matrix[version]
        assert entry["fmpy"] == {"status": "ok", "moves": True}
        for master, module in (("libcosim", "libcosimpy"), ("ecos", "ecospy")):
            row = entry[master]
            if _importable(module):
                assert row["status"] == "skipped" and module in row["reason"]
            elif row["status"] == "ok":
                # the same FMU calls at the same step: the same numbers to rounding (measured <= 7e-17 rad)
                assert row["max_abs_diff_to_fmpy"] < 1e-12, (version, master, row)
            else:
                assert (master, version, row["status"]) == ("libcosim", "fmi3", "failed"), row
                assert row["reason"] == "RuntimeError: libcosim crashed (SIGSEGV) running servo.fmu"


def test_timed_rounds_reports_a_failing_or_non_finite_run_and_keeps_timing_the_others():
    peers = _load("peers")
    calls = {"flaky": 0}

    def flaky():
        calls["flaky"] += 1
        if calls["flaky"] == 2:
            raise OSError("device vanished")
        return np.zeros(3)

    out = peers.timed_rounds({"good": lambda: np.ones(3), "flaky": flaky,
                              "nan": lambda: np.array([0.0, math.nan, 1.0]), "short": lambda: np.ones(2)}, 3, 3)
    record, walls, cpus = out["good"]
    assert np.array_equal(record, np.ones(3)) and len(walls) == len(cpus) == 3 and min(walls + cpus) >= 0
    assert out["flaky"] == "OSError: device vanished" and calls["flaky"] == 2
    assert out["nan"] == "RuntimeError: recorded 3 thrust samples, 1 not finite; expected 3 finite"
    assert out["short"] == "RuntimeError: recorded 2 thrust samples, 0 not finite; expected 3 finite"
