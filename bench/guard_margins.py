"""The margins behind the master's guards (cosim/guards.py): what they let through, what they stop.

Two measurements, each with the guards lifted so the raw numbers show:

* **energy ratio**: max over t >= one stroke period of (E(t) - E(0)) / W+(0, t), the feather's
  mechanical-energy gain over the positive work its root put in (the quantity the passive-energy
  guard holds below 2), and the gain beyond 2 W+ within the first period (why the guard waits a
  period), for accurate strong runs, weak couplings at the largest steps the step
  check allows, an unstable coupling and the added-mass runaways; plus what the same run does with
  the guards on (passes, refused, stopped and when);
* **recording grid**: the thrust ratio of the test bed's strong run recorded every 1-100 ms (the
  step check allows the shortest ramp / 25, 10 ms for the paper's 0.25 s ramps).

Writes <out>/guard_margins.json.

    python bench/guard_margins.py [--quick] [--out DIR]      (full: ~5 min; --quick: ~1 min)
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "stress"))

from stress_support import ENERGY, ROOT_RATE, TORQUE, plain_stroke_overrides, run_case  # noqa: E402

RESULTS = ROOT / "bench" / "results"
LIFTED = {"master.check_steps": False, "master.passive_energy_factor": 0.0}
PLAIN = {"feather.morphology": "plain"}


def _fastest(amplitude_deg: float, hold_s: float = 0.02) -> dict[str, float]:
    ramp = 1.875 * math.radians(amplitude_deg) / 6.2  # minimum-jerk ramp at the MG996R's 6.2 rad/s
    return plain_stroke_overrides(amplitude_deg, 2 * ramp + 2 * hold_s, ramp)


SWEEP = {"feather.morphology": "spanwise", "feather.width_m": 0.12, "controller.t_up_s": 0.1,
         "controller.t_down_s": 0.5, "controller.t_hold_up_s": 0, "controller.t_hold_down_s": 0}
THIN = {**PLAIN, "feather.length_m": 0.12, "feather.width_m": 0.09, "feather.thickness_m": 0.3e-3,
        "feather.added_mass_scale": 1.5, "master.periods": 9}
#: (name, group, scene, overrides, in --quick)
CASES: list[tuple[str, str, str, dict[str, Any], bool]] = [
    ("plain 60deg", "accurate", "kinematic", PLAIN, False),
    ("plain 120deg fastest", "accurate", "kinematic", {**PLAIN, **_fastest(120), "master.periods": 9}, False),
    ("chordwise WR 7.5", "accurate", "testbed", {}, True),
    ("chordwise WR 12 120deg", "accurate", "testbed", {"feather.width_ratio": 12, "controller.amplitude_deg": 120,
                                                       "controller.t_up_s": 0.4, "controller.t_down_s": 0.4}, False),
    ("spanwise LR 2", "accurate", "testbed", {"feather.morphology": "spanwise"}, False),
    ("spanwise LR 2 120deg", "accurate", "testbed", {"feather.morphology": "spanwise",
                                                     "controller.amplitude_deg": 120}, False),
    ("spanwise sweep l=90mm", "accurate", "testbed", {**SWEEP, "feather.length_m": 0.09}, False),
    ("plain jacobi 5 ms", "weak", "testbed", {**PLAIN, "master.coupling": "jacobi", "master.step_s": 5e-3}, False),
    ("plain gauss-seidel 10 ms", "weak", "testbed", {**PLAIN, "master.coupling": "gauss-seidel",
                                                     "master.step_s": 1e-2}, True),
    ("chordwise jacobi 5 ms", "weak", "testbed", {"master.coupling": "jacobi", "master.step_s": 5e-3}, False),
    ("spanwise gauss-seidel 10 ms", "weak", "testbed", {"feather.morphology": "spanwise",
                                                        "master.coupling": "gauss-seidel", "master.step_s": 1e-2},
     False),
    ("plain jacobi 10 ms (unstable)", "bad", "testbed", {**PLAIN, "master.coupling": "jacobi", "master.step_s": 1e-2},
     True),
    ("runaway 150x120 mm 60deg", "bad", "kinematic", {**PLAIN, "feather.length_m": 0.15, "feather.width_m": 0.12,
                                                      **_fastest(60), "master.periods": 9}, True),
    ("runaway thin sheet 120deg", "bad", "kinematic", {**THIN, **_fastest(120)}, False),
    ("runaway spanwise sweep l=110mm", "bad", "testbed", {**SWEEP, "feather.length_m": 0.11}, False),
]
GRIDS_S = (1e-3, 2e-3, 5e-3, 1e-2, 2.5e-2, 0.1)
GRIDS_QUICK_S = (1e-3, 1e-2, 2.5e-2)


def energy_margins(result: Any, scene: str) -> tuple[float, float]:
    """max over t >= one period of (E(t) - E(0)) / W+(0, t), W+ by the trapezoid rule (as the guard),
    and the largest gain beyond 2 W+ within the first period (J), which the guard does not judge."""
    t, energy = result.time, result[ENERGY]
    power = np.maximum(result[TORQUE] * result[ROOT_RATE[scene]], 0.0)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
    late = t >= result.summary["period_s"]
    gain = energy - energy[0]
    return float(np.max(gain[late] / work[late])), float(np.max(gain[~late] - 2 * work[~late]))


def with_guards(scene: str, overrides: dict[str, Any]) -> str:
    from featherstar.fmu_src.errors import FeatherstarError

    try:
        run_case(scene, overrides)
    except FeatherstarError as exc:
        t_s = getattr(exc, "t_s", None)
        return "refused before the run" if t_s is None else f"stopped at t = {t_s:.3g} s"
    return "passes"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 energy cases and 3 grids (about a minute)")
    parser.add_argument("--out", type=Path, default=RESULTS, help="output folder (default: bench/results)")
    args = parser.parse_args()
    t0 = time.perf_counter()
    report: dict[str, Any] = {"quick": args.quick, "energy": [], "grid": []}
    for name, group, scene, overrides, in_quick in CASES:
        if args.quick and not in_quick:
            continue
        result = run_case(scene, {**overrides, **LIFTED})
        ratio, early_excess_J = energy_margins(result, scene)
        row = {"case": name, "group": group, "scene": scene, "energy_ratio": ratio, "early_excess_J": early_excess_J,
               "peak_energy_J": float(np.max(result[ENERGY])), "thrust_ratio": result.summary["thrust_ratio"],
               "with_guards": with_guards(scene, overrides)}
        report["energy"].append(row)
        print(f"{name:32s} {group:9s} ratio {ratio:8.3g}  first period {1e3 * early_excess_J:8.3g} mJ  peak {row['peak_energy_J']:8.3g} J  "
              f"TR {row['thrust_ratio']:.3f}  guards: {row['with_guards']}", flush=True)
    for grid_s in GRIDS_QUICK_S if args.quick else GRIDS_S:
        for morphology in ("chordwise",) if args.quick else ("chordwise", "spanwise", "plain"):
            result = run_case("testbed", {"feather.morphology": morphology, "master.output_interval_s": grid_s,
                                          **LIFTED})
            report["grid"].append({"morphology": morphology, "output_interval_s": grid_s,
                                   "thrust_ratio": result.summary["thrust_ratio"]})
            print(f"grid {1e3 * grid_s:5.1f} ms {morphology:10s} TR {result.summary['thrust_ratio']:.4f}", flush=True)
    report["total_s"] = time.perf_counter() - t0
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "guard_margins.json"
    path.write_text(json.dumps(report, indent=2, default=float) + "\n")
    print(f"wrote {path} ({report['total_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
