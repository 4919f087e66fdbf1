"""Which recording tells the wake laws apart? A design criterion for model-form calibration.

    python bench/model_form_design.py [--out docs/results]

For each candidate recording design (a stroke of the testbed's 4-phase family and a number of
periods, the fit window covering all of them from rest) and each ordered pair of wake laws (A, B):
a noise-free recording of the plain feather whose wake follows law A (the emulator's FMU plant
stepped as the bench client drives it, bench_calibration._offline_run with no load-cell noise,
law A's fitted C_0 and added mass 1), and law B fitted to it by `calibrate` (scan + least squares
of B's C_0 and added mass, 40 ms bins): the best-fit residual RMS r_AB is what law B cannot
explain of law A's thrust. Law A fitted to its own recording gives the playback floor r_AA (the
recorded angle's quantisation and smoothing, the load cell's 5 ms integration), which is common
to every form.

Criterion, fixed before the hit-rate bench: with load-cell noise sd sigma per 40 ms bin (5 mN per
5 ms sample / sqrt(8) = 1.77 mN) and n bins in the fit (3 recordings x window / 40 ms), the
held-out comparison of forms A and B (featherstar.optimizer.calibration.forms.choose) sees a mean
squared-error difference of r_AB^2 - r_AA^2 against a standard error of about
2 sigma rms(m_B - m_A) / sqrt(n) (m: the noise-free residuals; `separation` has the exact
expression), i.e. z_AB ~ r_AB sqrt(n) / (2 sigma) when the floor is small, and choose() needs
z > 2 (TIE_SIGMAS); BIC's margin is about n ln((sigma^2 + r_AB^2) / (sigma^2 + r_AA^2)) and needs
>= 6. The design is the one with the largest min over pairs of
z_AB (maximin: the hardest pair decides), among those whose fit costs at most MAX_WINDOW_S of
simulated time per simulation.

Writes model_form_design.json into --out.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_calibration import _offline_run  # noqa: E402
from featherstar.fmu_src.fluid import WAKE_CONSTANTS, WAKE_LAWS  # noqa: E402
from featherstar.optimizer.calibration.fit import BIN_S, calibrate  # noqa: E402
from featherstar.optimizer.calibration.recordings import Recording  # noqa: E402

SCENE, OVERRIDES, PERIOD_S = "testbed", {"feather.morphology": "plain"}, 1.0
NOISE_PER_SAMPLE_N, SAMPLE_S, RECORDINGS = 0.005, 0.005, 3
SIGMA_BIN_N = NOISE_PER_SAMPLE_N / math.sqrt(BIN_S / SAMPLE_S)
THRUST_SAMPLES = "interval-mean"
MAX_WINDOW_S = 4.0
SYMMETRIC: dict = {}
ASYMMETRIC = {"controller.log10_up_down": 0.6, "controller.log10_hold_up_down": 0.0, "controller.log10_hold_move": -0.3}
#: name: (stroke overrides, periods in the fit window)
DESIGNS = {
    "symmetric-1": (SYMMETRIC, 1),
    "symmetric-3": (SYMMETRIC, 3),
    "asymmetric-1": (ASYMMETRIC, 1),
    "asymmetric-3": (ASYMMETRIC, 3),
    "asymmetric-4": (ASYMMETRIC, 4),
    "asymmetric-noholds-3": ({**ASYMMETRIC, "controller.log10_hold_move": -1.0}, 3),
    "asymmetric-longholds-3": ({**ASYMMETRIC, "controller.log10_hold_move": 0.3}, 3),
    "fast-power-3": ({**ASYMMETRIC, "controller.log10_up_down": 1.0}, 3),
    # twice the testbed's amplitude (±60°): the drag, and what the laws disagree on, grow as the
    # rate squared while the load cell's noise does not
    "symmetric-amp120-1": ({"controller.amplitude_deg": 120.0}, 1),
    "symmetric-amp120-3": ({"controller.amplitude_deg": 120.0}, 3),
    "asymmetric-amp120-1": ({**ASYMMETRIC, "controller.amplitude_deg": 120.0}, 1),
    "asymmetric-amp120-3": ({**ASYMMETRIC, "controller.amplitude_deg": 120.0}, 3),
    "asymmetric-amp120-4": ({**ASYMMETRIC, "controller.amplitude_deg": 120.0}, 4),
    "asymmetric-amp120-noholds-3": ({**ASYMMETRIC, "controller.amplitude_deg": 120.0,
                                     "controller.log10_hold_move": -1.0}, 3),
    "asymmetric-amp120-longholds-3": ({**ASYMMETRIC, "controller.amplitude_deg": 120.0,
                                       "controller.log10_hold_move": 0.3}, 3),
    # ±75°, inside MG996R's ±90° limits (hil.blocks.MG996R_LIMITS_RAD)
    "asymmetric-amp150-3": ({**ASYMMETRIC, "controller.amplitude_deg": 150.0}, 3),
}

#: The designs the committed JSON measured (about 3 min each at load 4 on 2 cores), in that order;
#: the others are defined, not measured (the search stopped once a design separated every pair).
MEASURED = ("asymmetric-3", "symmetric-1", "asymmetric-amp120-3", "asymmetric-amp150-3", "asymmetric-amp120-longholds-3")


def recording(law: str, stroke: dict, window_s: float) -> Recording:
    truth = {"wake_drag_coeff": WAKE_CONSTANTS[law][0], "added_mass_scale": 1.0}
    run = _offline_run("plain", {**stroke, "master.t_end_s": window_s + 0.2, "metrics.settle_periods": 0}, truth, 0,
                       {"wake": law}, noise_N=0.0)
    return Recording(f"{law}", run["time_s"], run["angle_rad"], run["thrust_N"], ("s", "rad", "N"), PERIOD_S)


def misfit(data: Recording, form: str, window_s: float) -> dict:
    started = time.perf_counter()
    fit = calibrate([data], SCENE, {**OVERRIDES, "feather.wake": form},
                    {"wake_drag_coeff": None, "added_mass_scale": None}, window_s=window_s, require_sd=False,
                    thrust_samples=THRUST_SAMPLES)
    residual = (fit.simulated_N - fit.measured_N)[0]
    return {"rms_N": fit.rms_residual_N, "values": fit.values, "simulations": fit.evaluations, "residual_N": residual,
            "thrust_rms_N": float(np.sqrt(np.mean(fit.measured_N**2))), "wall_s": round(time.perf_counter() - started, 1)}


def separation(own_N: np.ndarray, other_N: np.ndarray, n: int) -> dict:
    """How far the wrong form B is from the true form A on this design, with noise sigma per bin:
    the held-out comparison's statistic (featherstar.optimizer.calibration.forms.choose) on n bins
    whose noise-free residuals repeat (own_N, other_N) over the recordings. With e = noise + m,
    d = e_B^2 - e_A^2 has mean mean(m_B^2 - m_A^2) and variance 4 sigma^2 mean((m_B - m_A)^2) +
    var(m_B^2 - m_A^2); z = mean / sqrt(variance / n). BIC margin ~ n ln((sigma^2 + r_B^2) / (sigma^2 + r_A^2))."""
    d = other_N**2 - own_N**2
    variance = 4 * SIGMA_BIN_N**2 * float(np.mean((other_N - own_N) ** 2)) + float(np.var(d))
    r_a2, r_b2 = float(np.mean(own_N**2)), float(np.mean(other_N**2))
    return {"excess_rms_N": math.sqrt(max(r_b2 - r_a2, 0.0)), "z": float(np.mean(d)) / math.sqrt(variance / n),
            "bic_margin": n * math.log((SIGMA_BIN_N**2 + r_b2) / (SIGMA_BIN_N**2 + r_a2))}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    p.add_argument("--out", type=Path, default=Path("docs/results"))
    p.add_argument("--designs", default=",".join(MEASURED),
                   help=f"comma-separated, of {', '.join(DESIGNS)} (default: those measured in the committed JSON, "
                        "%(default)s)")
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "model_form_design.json"
    results = {"machine": {"load_average_at_start": list(os.getloadavg())},
               "setup": {"feather": "plain", "period_s": PERIOD_S, "laws": list(WAKE_LAWS), "sigma_bin_N": SIGMA_BIN_N, "bin_s": BIN_S,
                         "recordings": RECORDINGS, "thrust_samples": THRUST_SAMPLES, "max_window_s": MAX_WINDOW_S,
                         "criterion": "z_AB = mean(m_B^2 - m_A^2) / sqrt((4 sigma_bin^2 mean((m_B - m_A)^2) + var(m_B^2 - m_A^2)) / n), "
                                      "n = recordings x window / bin; "
                                      "design = argmax over designs of min over ordered pairs of z_AB"},
               "designs": {}}
    if path.exists():   # designs measured before are kept (one design per invocation is fine)
        results["designs"] = json.loads(path.read_text()).get("designs", {})
    names = args.designs.split(",")
    unknown = [n for n in names if n not in DESIGNS]
    if unknown:
        p.error(f"--designs {unknown[0]}: valid designs are {', '.join(DESIGNS)}")
    for name in names:
        stroke, periods = DESIGNS[name]
        window_s = periods * PERIOD_S
        n = RECORDINGS * round(window_s / BIN_S)
        row = {"stroke": stroke, "periods": periods, "window_s": window_s, "n_bins": n, "pairs": {}, "floor": {}}
        for law in WAKE_LAWS:
            data = recording(law, stroke, window_s)
            fits = {form: misfit(data, form, window_s) for form in WAKE_LAWS}
            own = fits[law]["residual_N"]
            row["floor"][law] = {k: v for k, v in fits[law].items() if k != "residual_N"}
            for form in WAKE_LAWS:
                m = fits[form]
                if form != law:
                    row["pairs"][f"{law}->{form}"] = {**{k: v for k, v in m.items() if k != "residual_N"},
                                                       **separation(own, m["residual_N"], n)}
                print(f"{name}: data {law}, form {form}: rms {m['rms_N'] * 1e3:.3f} mN"
                      + (f", z {row['pairs'][f'{law}->{form}']['z']:.1f}" if form != law else " (floor)")
                      + f" ({m['simulations']} sims, {m['wall_s']} s)", flush=True)
        row["min_z"] = min(m["z"] for m in row["pairs"].values())
        row["hardest_pair"] = min(row["pairs"], key=lambda k: row["pairs"][k]["z"])
        row["hardest_excess_rms_N"] = row["pairs"][row["hardest_pair"]]["excess_rms_N"]
        results["designs"][name] = row
        print(f"{name}: min z {row['min_z']:.2f} ({row['hardest_pair']})", flush=True)
        eligible = {k: v for k, v in results["designs"].items() if v["window_s"] <= MAX_WINDOW_S}
        results["chosen"] = max(eligible, key=lambda k: eligible[k]["min_z"])
        results["machine"]["load_average_at_end"] = list(os.getloadavg())
        path.write_text(json.dumps(results, indent=2) + "\n")
    print(f"chosen design: {results['chosen']}; wrote {path}")


if __name__ == "__main__":
    main()
