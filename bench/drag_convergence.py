"""Is the feather's thrust converged in its drag quadrature, its number of links and its tolerance?

Quadratic drag |s| s over a rigid strip whose normal speed s is affine along it is not a
polynomial where s changes sign, which a folding chordwise flap does over much of each stroke
(`featherstar.fmu_src.drag_quadrature`). Through the test bed scene (servo + feather, Adams), this
measures TR and mean thrust of
1. the drag rules: Gauss–Legendre points on each strip (1–32) and the rule split at the zero of s
   (1–8 points a side), on the chordwise feather under the symmetric and the optimizer's stroke and
   on the plain and spanwise feathers under the symmetric stroke; each rule's compiled RHS cost;
2. the number of links n_units (5, 10, 20, 40) at the default rule;
3. the master's tolerance rtol (1e-5 … 1e-8) at the default rule and n_units.
The default rule is the one with the fewest drag points per strip whose TR and mean thrust are
within 0.1 % of the finest rule's in every case; the finest is split, 8 points a side.

Writes <out>/drag_convergence.json and .png (default docs/results).

    python bench/drag_convergence.py [--out DIR]      (~12 min alone on 2 cores)
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from featherstar.cosim import run_scene  # noqa: E402
from featherstar.fmu_src.feather import DEFAULT_DRAG_POINTS, DEFAULT_DRAG_SPLIT, feather_model  # noqa: E402

from bench._rhs_cost import rhs_ns_per_evaluation  # noqa: E402

OPTIMIZED = {"controller.t_up_s": 0.32, "controller.t_hold_up_s": 0.84, "controller.t_down_s": 0.32,
             "controller.t_hold_down_s": 0.02}
CASES = {
    "chordwise, symmetric": {},
    "chordwise, optimized stroke": OPTIMIZED,
    "plain, symmetric": {"feather.morphology": "plain"},
    "spanwise, symmetric": {"feather.morphology": "spanwise"},
}
RULES = [(n, False) for n in (1, 2, 3, 4, 8, 16, 32)] + [(n, True) for n in (1, 2, 4, 8)]
FINEST = (8, True)
TOLERANCE = 1e-3  # relative: "converged" means within 0.1 % of the finest rule


def rule_name(points: int, split: bool) -> str:
    return f"{'split' if split else 'gauss'}-{points}"


def testbed(overrides: dict) -> dict:
    started = time.perf_counter()
    result = run_scene("testbed", overrides)
    return {"thrust_ratio": float(result.summary["thrust_ratio"]), "mean_thrust_N": float(result.summary["mean_thrust_N"]),
            "wall_s": time.perf_counter() - started}


def rhs_cost_us(points: int, split: bool) -> float:
    model = feather_model("chordwise", 10, drag_points=points, drag_split=split)
    x = np.random.default_rng(0).normal(0.0, 0.3, model.x.numel())  # flaps folding: s changes sign
    cost = rhs_ns_per_evaluation(model.function(), x, [0.3, 1.0, 5.0, 0.0], model.parameter_vector(), repeats=5)
    return cost["ns_median"] / 1e3


def run(out: Path) -> dict:
    started = time.perf_counter()
    result: dict = {"rules": {}, "n_units": {}, "rtol": {}}
    for points, split in RULES:
        name = rule_name(points, split)
        options = {"feather.drag_points": points, "feather.drag_split": split}
        row = {"rhs_us_chordwise_n10": rhs_cost_us(points, split),
               "cases": {case: testbed({**overrides, **options}) for case, overrides in CASES.items()}}
        result["rules"][name] = row
        print(name, f"{row['rhs_us_chordwise_n10']:.2f} us",
              {c: round(v["thrust_ratio"], 5) for c, v in row["cases"].items()}, flush=True)
    select(result)
    for n_units in (5, 10, 20, 40):
        result["n_units"][str(n_units)] = {case: testbed({**CASES[case], "feather.n_units": n_units})
                                           for case in ("chordwise, symmetric", "plain, symmetric")}
        print("n_units", n_units, result["n_units"][str(n_units)], flush=True)
    for rtol in (1e-5, 1e-6, 1e-7, 1e-8):
        result["rtol"][f"{rtol:g}"] = {case: testbed({**CASES[case], "master.rtol": rtol, "master.atol": rtol / 100})
                                       for case in ("chordwise, symmetric", "plain, symmetric")}
        print("rtol", rtol, result["rtol"][f"{rtol:g}"], flush=True)
    result["seconds"] = time.perf_counter() - started
    out.mkdir(parents=True, exist_ok=True)
    (out / "drag_convergence.json").write_text(json.dumps(result, indent=1))
    plot(result, out / "drag_convergence.png")
    return result


def select(result: dict) -> None:
    """Each rule's largest relative deviation from the finest over the cases' TR and mean thrust,
    and the converged rule with the fewest drag points per strip (a split rule has points on both
    sides; the measured µs, taken on a shared machine, order the rules the same way but noisily)."""
    finest = result["rules"][rule_name(*FINEST)]["cases"]
    for row in result["rules"].values():
        row["max_relative_error"] = max(abs(row["cases"][c][k] / finest[c][k] - 1) for c in CASES
                                        for k in ("thrust_ratio", "mean_thrust_N"))
    converged = [(points * (2 if split else 1), split, rule_name(points, split)) for points, split in RULES
                 if result["rules"][rule_name(points, split)]["max_relative_error"] <= TOLERANCE]
    result["first_converged_rule"] = min(converged)[2]
    result["default_rule"] = rule_name(DEFAULT_DRAG_POINTS, DEFAULT_DRAG_SPLIT)


def plot(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from featherstar.cosim.plotstyle import save_figure

    fig, (rule_ax, n_ax, tol_ax) = plt.subplots(1, 3, figsize=(15, 4.2))
    finest = result["rules"][rule_name(*FINEST)]["cases"]
    for case in CASES:
        for split, marker in ((False, "o-"), (True, "s--")):
            rows = [(p, result["rules"][rule_name(p, s)]) for p, s in RULES if s == split]
            error = [max(abs(r["cases"][case]["thrust_ratio"] / finest[case]["thrust_ratio"] - 1), 1e-9) for _, r in rows]
            rule_ax.loglog([p for p, _ in rows], error, marker, label=f"{case}, {'split' if split else 'Gauss'}")
    rule_ax.axhline(TOLERANCE, color="k", lw=0.8, ls=":")
    rule_ax.set(xlabel="drag points per strip (per side when split)", ylabel="|TR / TR(split-8) − 1|",
                title="Drag quadrature (test bed)")
    rule_ax.legend(fontsize=6)
    for case in ("chordwise, symmetric", "plain, symmetric"):
        units = sorted(result["n_units"], key=int)
        n_ax.plot([int(u) for u in units], [result["n_units"][u][case]["thrust_ratio"] for u in units], "o-", label=case)
        tols = sorted(result["rtol"], key=float)
        tol_ax.semilogx([float(t) for t in tols], [result["rtol"][t][case]["thrust_ratio"] for t in tols], "o-",
                        label=case)
    n_ax.set(xlabel="N units", ylabel="TR", title=f"Links (rule {result['default_rule']})")
    tol_ax.set(xlabel="master rtol (atol = rtol/100)", ylabel="TR", title="Solver tolerance")
    n_ax.legend(fontsize=8)
    tol_ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results", help="where the JSON and plot go")
    run(parser.parse_args(argv).out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
