"""Stability map of the couplings: the largest stable macro step versus contact stiffness and N.

The weak couplings (Jacobi, Gauss–Seidel) hold every coupled input constant over a macro step H.
On the `testbed` (controller -> servo -> feather, the feather's root torque fed back to the servo)
that hold closes a loop whose energy error grows with H until the run blows up. For each cell
(morphology, N units, hinge contact stiffness) and each weak coupling this bench scans H upwards
on a fixed grid and records, against a strong-coupling reference run of the same case:

* **bounded edge**: the largest H below which every run completes, stays finite, creates no net
  energy (mean root power >= 0), does not grow its peak energy from period to period and keeps it
  within 3x the reference's. Past it the run blows up, or stops with a StepError.
* **checks edge**: the largest H below which every run passes all the physical checks of the stress
  suite (tests/stress/stress_support.py, the same code): the bounded conditions plus the interface
  energy balance (no interval gains more energy than the root put in, within 10 % of the peak
  energy for the plain feather, 75 % for the flapped ones) and a periodic steady state.

Strong coupling has no macro step (one CVODE over all states, inputs exact inside the right-hand
side); the bench records whether its run passes the checks and what it costs (RHS evaluations).
The kinematic scene has no feedback loop, so a weak coupling there cannot go unstable; it only
loses accuracy (see docs/stability.md for the sampling limit of the macro step).

Cells (full): plain N = 2, 5, 10, 20 and spanwise N = 2, 4, 10, 20 at the default contact
stiffness; spanwise N = 10 at 1x, 10x, 100x, 1000x and chordwise N = 10 at 1x and 1000x the default
contact stiffness; --n40 adds plain N = 40 on a short grid (its FMU evaluates in ~0.5 ms: minutes
per run). --quick: plain N = 5, 10 and spanwise N = 10 at 1x and 1000x on a shorter grid.
Runs are 5 periods of the paper's stroke; the checks use the last 2.

Writes <out>/stability_map.json and <out>/stability_map.png.

    python bench/stability_map.py [--quick] [--out DIR]      (full: ~15 min; --quick: ~1 min)
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any, Sequence

ROOT = Path(__file__).resolve().parents[1]
# The map's "passes the checks" is exactly what the stress tests accept: one definition, one code.
sys.path.insert(0, str(ROOT / "tests" / "stress"))

from stress_support import metrics_of, physical_problems, run_case, tolerances  # noqa: E402

RESULTS = ROOT / "bench" / "results"
SCENE = "testbed"
COUPLINGS = ("jacobi", "gauss-seidel")
DEFAULT_STEP_S = 1e-3  # the shipped scenes' master.step_s
DEFAULT_CONTACT = 10.0  # contact_stiffness_Nm_rad_m default
GRID_FULL = (5e-4, 1e-3, 1.5e-3, 2e-3, 3e-3, 4e-3, 5e-3, 7e-3, 1e-2, 1.5e-2, 2e-2, 3e-2, 5e-2, 0.1)
GRID_QUICK = (1e-3, 2e-3, 3e-3, 5e-3, 8e-3, 1.2e-2, 2e-2, 5e-2)
GRID_N40 = (1e-3, 3e-3, 5e-3, 8e-3)  # N = 40: each run costs minutes (0.5 ms per right-hand side)
#: "bounded": peak energy within this factor of the strong reference's (plain; flapped: chaotic, 5x)
BOUNDED_ENERGY_FACTOR = {"plain": 3.0, "flapped": 5.0}


def cells(quick: bool, n40: bool = False) -> list[dict[str, Any]]:
    def cell(morph: str, n: int, factor: float, axis: str) -> dict[str, Any]:
        return {"morphology": morph, "n_units": n, "contact_factor": factor, "axis": axis}

    if quick:
        return [cell("plain", 5, 1, "N"), cell("plain", 10, 1, "N"),
                cell("spanwise", 10, 1, "stiffness"), cell("spanwise", 10, 1000, "stiffness")]
    out = [cell("plain", n, 1, "N") for n in (2, 5, 10, 20)]
    out += [cell("spanwise", n, 1, "N") for n in (2, 4, 10, 20)]
    out += [cell("spanwise", 10, f, "stiffness") for f in (1, 10, 100, 1000)]
    out += [cell("chordwise", 10, f, "stiffness") for f in (1, 1000)]
    if n40:
        out.insert(4, cell("plain", 40, 1, "N"))
    return out


def overrides(cell: dict[str, Any], periods: int) -> dict[str, Any]:
    o: dict[str, Any] = {"feather.morphology": cell["morphology"], "feather.n_units": cell["n_units"],
                         "master.periods": periods, "metrics.settle_periods": periods - 2}
    if cell["morphology"] != "plain":
        o["feather.contact_stiffness_Nm_rad_m"] = DEFAULT_CONTACT * cell["contact_factor"]
    return o


def classify(result: Any, reference: dict[str, Any], morphology: str) -> tuple[str, list[str], dict[str, Any]]:
    m = metrics_of(result, SCENE)
    problems = physical_problems(result, SCENE, morphology)
    factor = BOUNDED_ENERGY_FACTOR["plain" if morphology == "plain" else "flapped"]
    bounded = (m["all_finite"] and math.isfinite(m["thrust_ratio"]) and m["mean_root_power_W"] >= 0
               and m.get("energy_growth", 1.0) <= tolerances(morphology).growth
               and m["peak_energy_J"] <= factor * reference["peak_energy_J"])
    status = "ok" if not problems else ("fails-checks" if bounded else "unbounded")
    return status, problems, m


def scan_cell(cell: dict[str, Any], grid: Sequence[float], periods: int, log) -> dict[str, Any]:
    from featherstar.fmu_src.errors import FeatherstarError

    # The map measures the raw edges the master's guards are set from (cosim/guards.py), so
    # they are off here: past the edge a run must show what it does, not be refused.
    base = {**overrides(cell, periods), "master.check_steps": False, "master.passive_energy_factor": 0.0}
    label = f"{cell['morphology']} N={cell['n_units']} k={cell['contact_factor']:g}x"
    entry: dict[str, Any] = {**cell, "overrides": base, "strong": {}, "weak": {}}
    t0 = time.perf_counter()
    try:
        ref = run_case(SCENE, {**base, "master.coupling": "strong"})
    except FeatherstarError as exc:
        entry["strong"] = {"error": str(exc)}
        log(f"[{label}] strong FAILED: {exc}")
        return entry
    rm = metrics_of(ref, SCENE)
    rp = physical_problems(ref, SCENE, cell["morphology"])
    entry["strong"] = {"metrics": rm, "problems": rp, "wall_s": time.perf_counter() - t0,
                       "rhs_evals": ref.summary["stats"].get("rhs_evals"), "steps": ref.summary["stats"].get("steps")}
    log(f"[{label}] strong: TR {rm['thrust_ratio']:.4f}, {'passes' if not rp else 'FAILS: ' + '; '.join(rp)} "
        f"({entry['strong']['wall_s']:.1f} s, {entry['strong']['rhs_evals']} RHS)")
    for coupling in COUPLINGS:
        runs = []
        bounded_edge = checks_edge = 0.0
        bounded_ok = checks_ok = True
        bad_in_a_row = 0
        for h in grid:
            t1 = time.perf_counter()
            row: dict[str, Any] = {"step_s": h}
            try:
                r = run_case(SCENE, {**base, "master.coupling": coupling, "master.step_s": h})
                status, problems, m = classify(r, rm, cell["morphology"])
                row.update(status=status, problems=problems, thrust_ratio=m["thrust_ratio"],
                           tr_error=abs(m["thrust_ratio"] - rm["thrust_ratio"]) / abs(rm["thrust_ratio"]),
                           peak_energy_ratio=m["peak_energy_J"] / rm["peak_energy_J"],
                           energy_balance_residual=m["energy_balance_residual"],
                           mean_root_power_W=m["mean_root_power_W"])
            except FeatherstarError as exc:
                status = "error"
                row.update(status=status, error=str(exc))
            row["wall_s"] = time.perf_counter() - t1
            runs.append(row)
            bounded_ok = bounded_ok and status in ("ok", "fails-checks")
            checks_ok = checks_ok and status == "ok"
            if bounded_ok:
                bounded_edge = h
            if checks_ok:
                checks_edge = h
            log(f"[{label}] {coupling:<12} H={1e3 * h:6.2f} ms {status:<12} "
                + (f"TR {row['thrust_ratio']:.4f} (err {row['tr_error']:.1e}) E/Eref {row['peak_energy_ratio']:.2f} "
                   f"balance {row['energy_balance_residual']:.2f}" if "thrust_ratio" in row else row.get("error", ""))
                + f" ({row['wall_s']:.1f} s)")
            bad_in_a_row = bad_in_a_row + 1 if status in ("unbounded", "error") else 0
            if bad_in_a_row >= 2:
                break
        entry["weak"][coupling] = {
            "runs": runs, "bounded_edge_s": bounded_edge, "checks_edge_s": checks_edge,
            # the scan never found the edge: it lies above the largest step tried
            "bounded_edge_is_lower_bound": bounded_ok, "checks_edge_is_lower_bound": checks_ok,
            "first_bounded_fail_s": next((r["step_s"] for r in runs if r["status"] in ("unbounded", "error")), None)}
    entry["wall_s"] = time.perf_counter() - t0
    return entry


def plot(report: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from featherstar.cosim.plotstyle import save_figure

    entries = [e for e in report["cells"] if e.get("weak")]
    panels = [("N", "plain"), ("N", "spanwise"), ("stiffness", "spanwise"), ("stiffness", "chordwise")]
    panels = [p for p in panels if any(e["axis"] == p[0] and e["morphology"] == p[1] for e in entries)]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 4.2), squeeze=False, constrained_layout=True)
    for ax, (axis, morph) in zip(axes[0], panels):
        cell_list = sorted((e for e in entries if e["axis"] == axis and e["morphology"] == morph),
                           key=lambda e: e["n_units"] if axis == "N" else e["contact_factor"])
        xs = [e["n_units"] if axis == "N" else e["contact_factor"] for e in cell_list]
        for i, coupling in enumerate(COUPLINGS):
            for key, ls, mk, what in (("bounded_edge_s", "-", "os"[i], "bounded"),
                                      ("checks_edge_s", "--", "xd"[i], "passes checks")):
                # a slight offset keeps coinciding curves apart; hollow markers: edge above the grid
                xo = [x * (1.04 if i else 0.96) for x in xs]
                ys = [1e3 * e["weak"][coupling][key] if e["weak"][coupling][key] else float("nan") for e in cell_list]
                ax.plot(xo, ys, ls, marker=mk, color=f"C{i}", label=f"{coupling}: {what}")
                lower = [e["weak"][coupling][key.replace("_s", "_is_lower_bound")] for e in cell_list]
                ax.plot([x for x, lb in zip(xo, lower) if lb], [y for y, lb in zip(ys, lower) if lb], "^",
                        color=f"C{i}", ms=11, mfc="none")
        ax.axhline(1e3 * DEFAULT_STEP_S, color="k", lw=0.8, ls=":", label="default step (1 ms)")
        if axis == "stiffness":
            ax.axvline(1, color="0.6", lw=0.6)
            ax.set_xscale("log")
            ax.set_xlabel("contact stiffness / default (10 N·m/rad/m)")
        else:
            ax.set_xscale("log")
            ax.set_xticks(xs, [str(x) for x in xs])
            ax.minorticks_off()
            ax.set_xlabel("N units")
            ax.axvline(10, color="0.6", lw=0.6)
        ax.set_yscale("log")
        ax.set_ylabel("largest stable macro step (ms)")
        ax.set_title(f"testbed, {morph}")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.suptitle("Largest stable macro step of the weak couplings (hollow triangle: no failure up to there; "
                 "strong coupling has no macro step)", fontsize=10)
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def summary_lines(report: dict[str, Any]) -> list[str]:
    lines = []
    for e in report["cells"]:
        label = f"{e['morphology']} N={e['n_units']} k={e['contact_factor']:g}x"
        if "skipped" in e:
            lines.append(f"{label}: skipped ({e['skipped']})")
            continue
        parts = []
        for c in COUPLINGS:
            w = e.get("weak", {}).get(c)
            if w:
                b = ">=" if w["bounded_edge_is_lower_bound"] else "<="
                k = ">=" if w["checks_edge_is_lower_bound"] else "<="
                parts.append(f"{c} bounded {b} {1e3 * w['bounded_edge_s']:g} ms, checks {k} {1e3 * w['checks_edge_s']:g} ms")
        strong = e.get("strong", {})
        s = "strong " + ("passes" if not strong.get("problems") and "metrics" in strong else "FAILS")
        lines.append(f"{label}: {s}; " + "; ".join(parts))
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="4 cells, shorter grid and runs (about a minute)")
    parser.add_argument("--out", type=Path, default=RESULTS, help="output folder (default bench/results)")
    parser.add_argument("--n40", action="store_true",
                        help="add plain N = 40 on a short grid (cold FMU build ~6.5 min; ~220 s per run)")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()

    def log(msg: str) -> None:
        print(f"{time.perf_counter() - t0:7.1f}s {msg}", flush=True)

    periods = 5  # the plain feather needs 3 periods to settle to 2 % (periodicity check)
    grid = GRID_QUICK if args.quick else GRID_FULL
    report: dict[str, Any] = {
        "scene": SCENE, "quick": args.quick, "periods": periods, "metric_periods": 2, "grid_s": list(grid),
        "default_step_s": DEFAULT_STEP_S, "default_contact_stiffness": DEFAULT_CONTACT,
        "machine": {"cpus": os.cpu_count(), "load_avg_1min_at_start": os.getloadavg()[0],
                    "python": platform.python_version(), "platform": platform.platform()},
        "definitions": {
            "bounded": "completes, finite, mean root power >= 0, peak energy growth over the window <= 1.5x "
                       "(flapped, chaotic: 3x), peak energy <= 3x the strong reference's (flapped: 5x)",
            "passes checks": "tests/stress/stress_support.physical_problems() finds nothing",
            "edge": "largest grid step below which every step has the property (scan stops after two "
                    "unbounded or failed runs in a row)",
        },
        "cells": [],
    }
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    path = out / "stability_map.json"
    scanned: dict[tuple, dict[str, Any]] = {}
    for cell in cells(args.quick, args.n40):
        key = (cell["morphology"], cell["n_units"], cell["contact_factor"])
        if key in scanned:  # the same cell on the other axis (spanwise N = 10 at 1x): scan once
            report["cells"].append({**scanned[key], "axis": cell["axis"]})
            continue
        cell_grid = GRID_N40 if cell["n_units"] >= 40 else grid
        scanned[key] = scan_cell(cell, cell_grid, periods, log)
        report["cells"].append(scanned[key])
        path.write_text(json.dumps(report, indent=2, default=float) + "\n")
    report["machine"]["load_avg_1min_at_end"] = os.getloadavg()[0]
    report["total_s"] = time.perf_counter() - t0
    report["summary"] = summary_lines(report)
    path.write_text(json.dumps(report, indent=2, default=float) + "\n")
    plot(report, out / "stability_map.png")
    for line in report["summary"]:
        log(line)
    log(f"wrote {path} and stability_map.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
