"""What makes the flapped feathers directional, and how much it hangs on the tape hinge.

Under the paper's symmetric stroke (N = 10, direct CasADi integration, last 3 of 6 periods):
* the spanwise feather (LR 2) with its root part held by the support (the default,
  `root_support = true`) and bending freely (`root_support = false`), each with the oscillatory
  drag law and with the steady coefficient C_n = 1.2, and at the ends of the tape's
  hinge-stiffness range; the plot shows fold angle and thrust over one period for both layouts;
* the chordwise feather (WR 7.5) across the hinge stiffness 1e-4 (the old default) to 1e-1.
Records TR, mean thrust and the fold angle range.

Writes <out>/flap_mechanisms.json and <out>/spanwise_mechanism.png (default docs/results).

    python bench/flap_mechanisms.py [--out DIR]      (~4 min on 2 cores)
"""
from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from featherstar.cosim.swimmer.stroke import Stroke, root_motion_symbolic  # noqa: E402
from featherstar.fmu_src.feather import feather_model  # noqa: E402
from featherstar.fmu_src.integrate import integrate  # noqa: E402

PERIODS, SETTLE, PER_PERIOD = 6, 3, 600
CASES = {
    "chordwise, k_h 1e-4": ("chordwise", {}, {"hinge_stiffness_Nm_rad_m": 1e-4}),
    "chordwise, k_h 1e-3": ("chordwise", {}, {"hinge_stiffness_Nm_rad_m": 1e-3}),
    "chordwise, k_h 1e-2 (default)": ("chordwise", {}, {}),
    "chordwise, k_h 1e-1": ("chordwise", {}, {"hinge_stiffness_Nm_rad_m": 1e-1}),
    "supported": ("spanwise", {"root_support": True}, {}),
    "supported, C_n 1.2": ("spanwise", {"root_support": True}, {"oscillatory_drag": 0.0}),
    "supported, k_h 1e-3": ("spanwise", {"root_support": True}, {"hinge_stiffness_Nm_rad_m": 1e-3}),
    "supported, k_h 1e-1": ("spanwise", {"root_support": True}, {"hinge_stiffness_Nm_rad_m": 1e-1}),
    "free root part": ("spanwise", {"root_support": False}, {}),
    "free root part, C_n 1.2": ("spanwise", {"root_support": False}, {"oscillatory_drag": 0.0}),
}


def run(morphology: str, options: dict, parameters: dict, stroke: Stroke) -> dict:
    model = feather_model(morphology, 10, **options)

    def drive(t):
        angle, rate, accel = root_motion_symbolic(
            t, stroke.t_up_s, stroke.t_hold_up_s, stroke.t_down_s, stroke.t_hold_down_s, stroke.amplitude_rad)
        return ca.vertcat(angle, rate, accel, 0.0)

    grid = np.linspace(0, PERIODS * stroke.period_s, PERIODS * PER_PERIOD + 1)
    start = time.perf_counter()
    _, y = integrate(model, grid, drive, parameters, rtol=1e-7, atol=1e-9)
    wall_s = time.perf_counter() - start
    window = slice(SETTLE * PER_PERIOD, PERIODS * PER_PERIOD)  # whole periods, end excluded
    thrust, fold = y[window, 0], y[window, 4]
    last = slice((PERIODS - 1) * PER_PERIOD, PERIODS * PER_PERIOD + 1)
    return {
        "thrust_ratio": float(thrust[thrust > 0].sum() / -thrust[thrust < 0].sum()),
        "mean_thrust_mN": 1e3 * float(thrust.mean()),
        "fold_max_deg": math.degrees(float(fold.max())),
        "fold_min_deg": math.degrees(float(fold.min())),
        "wall_s": wall_s,
        "last_period": {"t_s": (grid[last] - grid[last][0]).tolist(), "thrust_N": y[last, 0].tolist(),
                        "fold_rad": y[last, 4].tolist()},
    }


def plot(results: dict, stroke: Stroke, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from featherstar.cosim.plotstyle import save_figure

    fig, (ax_fold, ax_thrust) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    for name in ("supported", "free root part"):
        period = results[name]["last_period"]
        label = f"{name} (TR {results[name]['thrust_ratio']:.2f})"
        ax_fold.plot(period["t_s"], np.degrees(period["fold_rad"]), label=label)
        ax_thrust.plot(period["t_s"], 1e3 * np.array(period["thrust_N"]), label=label)
    for ax in (ax_fold, ax_thrust):
        ax.axvspan(0, stroke.t_up_s, color="0.9", zorder=0)
        ax.axvspan(stroke.t_up_s + stroke.t_hold_up_s, stroke.t_up_s + stroke.t_hold_up_s + stroke.t_down_s,
                   color="0.8", zorder=0)
    ax_fold.set_ylabel("hinge fold angle (deg)")
    ax_thrust.set_ylabel("thrust (mN)")
    ax_thrust.set_xlabel("time in the last period (s); light: upstroke, dark: downstroke")
    ax_fold.legend()
    ax_fold.set_title("Spanwise LR 2, symmetric stroke: held root part vs free root part")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results", help="output directory")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    stroke = Stroke()
    results = {}
    for name, (morphology, options, parameters) in CASES.items():
        results[name] = run(morphology, options, parameters, stroke)
        r = results[name]
        print(f"{name:26s} TR {r['thrust_ratio']:.2f}  mean {r['mean_thrust_mN']:7.2f} mN  "
              f"fold {r['fold_min_deg']:.0f}..{r['fold_max_deg']:.0f} deg  ({r['wall_s']:.1f} s)", flush=True)
    plot(results, stroke, args.out / "spanwise_mechanism.png")
    for r in results.values():
        r.pop("last_period")
    (args.out / "flap_mechanisms.json").write_text(json.dumps(
        {"stroke": vars(stroke), "periods": PERIODS, "settle_periods": SETTLE, "cases": results}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
