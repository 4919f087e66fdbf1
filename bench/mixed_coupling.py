"""Mixed coupling against weak coupling: accuracy and wall time on one scene, side by side.

The test bed with a co-simulation-only command filter (a first-order lag, tau 20 ms, the FMI 2.0
test FMU of tests/cosim/fmi2_lag seen through its CS interface) between the stroke controller
and the servo. Reference: the filter as Model Exchange, everything strongly coupled at rtol 1e-10.
For each communication step: mixed (the servo and feather one ODE, the filter stepped), Jacobi and
Gauss-Seidel (mixed also with Adams fixed-point iteration); the relative error of TR and mean thrust, and wall time as a ratio to mixed's in
the same run (this machine is noisy: compare ratios).

    python bench/mixed_coupling.py [--quick] [--out DIR]    # JSON and plot (default docs/results)
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "cosim"))  # the test FMUs' builder and scene (not a package)

from lag_fmu import build_lag_fmu  # noqa: E402
from test_mixed_coupling import filtered_testbed  # noqa: E402

from featherstar.cosim.swimmer.run import run_scene  # noqa: E402

#: (label, coupling, master.method): the scene's Adams-Newton, and Adams with fixed-point iteration,
#: which needs no Jacobian after each of the mixed coupling's solver restarts
VARIANTS = (("mixed", "mixed", "adams"), ("mixed, adams-fixedpoint", "mixed", "adams-fixedpoint"),
            ("jacobi", "jacobi", "adams"), ("gauss-seidel", "gauss-seidel", "adams"))


def measure(fmu: Path, steps_s: list[float], periods: int) -> dict:
    short = {"master.periods": periods, "metrics.settle_periods": periods - 2}
    t0 = time.perf_counter()
    ref = run_scene(filtered_testbed(fmu, "me"), {**short, "master.coupling": "strong", "master.rtol": 1e-10,
                                                  "master.atol": 1e-12})
    rows = [{"coupling": "strong (reference, filter as ME)", "wall_s": time.perf_counter() - t0,
             "thrust_ratio": ref.summary["thrust_ratio"], "mean_thrust_N": ref.summary["mean_thrust_N"]}]
    scene = filtered_testbed(fmu, "cs")
    for step_s in steps_s:
        for label, coupling, method in VARIANTS:
            t0 = time.perf_counter()
            r = run_scene(scene, {**short, "master.coupling": coupling, "master.method": method, "master.step_s": step_s})
            wall = time.perf_counter() - t0
            rows.append({"coupling": label, "step_s": step_s, "wall_s": wall,
                         "tr_rel_error": abs(r.summary["thrust_ratio"] / ref.summary["thrust_ratio"] - 1),
                         "mean_thrust_rel_error": abs(r.summary["mean_thrust_N"] / ref.summary["mean_thrust_N"] - 1)})
            print(f"{label:24s} step {step_s:g} s: TR error {rows[-1]['tr_rel_error']:.2e}, mean thrust error "
                  f"{rows[-1]['mean_thrust_rel_error']:.2e}, {wall:.2f} s", flush=True)
    for row in rows[1:]:
        mixed = next(r for r in rows[1:] if r["coupling"] == "mixed" and r["step_s"] == row["step_s"])
        row["wall_over_mixed"] = row["wall_s"] / mixed["wall_s"]
        row["tr_error_over_mixed"] = row["tr_rel_error"] / max(mixed["tr_rel_error"], 1e-300)
    return {"periods": periods, "load_average_at_start": os.getloadavg()[0], "rows": rows}


def plot(result: dict, out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from featherstar.cosim.plotstyle import save_figure

    fig, ax = plt.subplots(figsize=(6, 4))
    for (label, _, _), marker in zip(VARIANTS, "o^sd"):
        rows = [r for r in result["rows"] if r["coupling"] == label]
        ax.loglog([r["wall_s"] for r in rows], [r["tr_rel_error"] for r in rows], marker=marker, label=label)
        for r in rows:
            ax.annotate(f"{r['step_s'] * 1e3:g} ms", (r["wall_s"], r["tr_rel_error"]), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel("TR relative error against the tight reference")
    ax.set_title("Test bed with a CS-only command filter: work against precision")
    ax.legend(title="coupling")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    save_figure(fig, out / "mixed_coupling.png", dpi=110)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two steps, four periods (about 20 s)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results", help="where the JSON and plot go")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    steps = [1e-3, 5e-4] if args.quick else [2e-3, 1e-3, 5e-4, 2.5e-4]
    with tempfile.TemporaryDirectory() as folder:
        result = measure(build_lag_fmu(Path(folder)), steps, 4 if args.quick else 6)
    (args.out / "mixed_coupling.json").write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    plot(result, args.out)
    print(f"wrote {args.out / 'mixed_coupling.json'} and .png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
