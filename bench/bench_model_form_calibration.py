"""Model-form calibration against the emulator's plant: is the true wake law picked, and its coefficients recovered?

    python bench/bench_model_form_calibration.py [--quick] [--seeds 5] [--out docs/results] [--skip-realtime]
        [--stroke symmetric|asymmetric] [--periods N] [--design NAME] [--realtime-cases]

For each true law (none / relative / self / plate) and seed: the emulator's plant (the FMU plant,
featherstar.hil.fmu_plant.FmuPlant, with that `wake` build option, as `featherstar emulate
--plant-set feather.wake=LAW` runs it) gets hidden coefficients drawn per seed from HIDDEN_RANGES;
three recordings of the testbed's symmetric 1 s stroke are made (each with its own noise seed), and
`featherstar.optimizer.calibration.forms.calibrate_forms` fits every form to them and chooses one.
Reported: the hit rate per law (chosen form = true law), each form's held-out RMS and BIC, and
the true form's coefficient errors.

Recordings: the plant stepped in simulated time exactly as the bench client drives it
(bench/bench_calibration.py `_offline_run`: 5 ms steps, stroke rate-limited, angle in 0.01°,
the load cell's mean force per step, 5 mN noise, tare at 0.3 s), not the real-time emulator: a
calibration case costs minutes of fitting, and a 2-core machine shared by several users cannot
keep 250 Hz for 60 real-time runs. One real-time recording through `featherstar emulate` (a
child process with the plate law hidden, `featherstar run --hardware`'s loop) is checked end to
end: its thrust against the offline recording of the same plant, and the chosen form's
prediction of it (unless --skip-realtime).

The feather is the plain one (no hinge, so two coefficients per form: drag and added mass;
its fits are the cheapest). `--quick`: one seed, the laws none and plate, two forms each.
`--realtime-cases`: the cases' three recordings are made through the real-time emulator instead
(device-timed, a fresh emulator per recording; `realtime_recordings`), the end-to-end check of a
design; written to ..._realtime.json.
`--periods N`: record N stroke periods (+ 0.2 s) and fit all N (the fit window; default 1).
`--design NAME`: the stroke and periods of one of bench/model_form_design.py's DESIGNS (that
script chooses the design that tells the wake laws apart, before this bench runs).
Writes bench_model_form_calibration[_STROKE][_Nperiods].json (after every case, so a partial
run keeps its cases) and .png into --out.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_calibration import _offline_run, _urls  # noqa: E402
from model_form_design import DESIGNS  # noqa: E402
from featherstar.cosim.plotstyle import save_figure  # noqa: E402
from featherstar.fmu_src.fluid import WAKE_CONSTANTS  # noqa: E402
from featherstar.hil.emulator import spawn_emulator  # noqa: E402
from featherstar.optimizer.bench.objective import discard_reasons  # noqa: E402
from featherstar.optimizer.bench.run import BenchFault, run_on_bench  # noqa: E402
from featherstar.optimizer.calibration.fit import predict  # noqa: E402
from featherstar.optimizer.calibration.forms import FORMS, calibrate_forms  # noqa: E402
from featherstar.optimizer.calibration.recordings import Recording  # noqa: E402

MORPHOLOGY, PERIOD_S, RUNS = "plain", 1.0, 3
# the fit window and the recordings' length (set by --periods: N periods, + 0.2 s)
DESIGN = {"window_s": 1.0, "record_s": 1.2}
SCENE, OVERRIDES = "testbed", {"feather.morphology": MORPHOLOGY}
# Hidden coefficients per seed, uniform in: the quasi-steady constant drag around the
# oscillating plate's (steady 1.2, oscillatory KC drag above it), a wake law's C_0 within 25 % of
# its fitted value (fmu_src.fluid.WAKE_CONSTANTS), the added mass within 20 % of the DNV estimate.
HIDDEN_RANGES = {"drag_coeff": (1.2, 2.0), "wake_drag_coeff_factor": (0.8, 1.25), "added_mass_scale": (0.8, 1.2)}
COEFFICIENT_TOLERANCE = 0.15
# the recordings' load cell reports the mean force over each 5 ms step, stamped at its end
THRUST_SAMPLES = "interval-mean"
# --stroke: the testbed's symmetric baseline, or a fast downstroke and a slow return (the
# optimizer's kind of stroke, where the wake laws' impulses differ most: issue 26)
STROKES = {"symmetric": {}, "asymmetric": {"controller.log10_up_down": 0.6, "controller.log10_hold_up_down": 0.0,
                                           "controller.log10_hold_move": -0.3}}
STROKE = dict(STROKES["symmetric"])


def hidden(law: str, seed: int) -> dict[str, float]:
    rng = np.random.default_rng(1000 + seed)
    drag = rng.uniform(*HIDDEN_RANGES["drag_coeff"])
    factor = rng.uniform(*HIDDEN_RANGES["wake_drag_coeff_factor"])
    added = float(rng.uniform(*HIDDEN_RANGES["added_mass_scale"]))
    if law == "none":   # a constant drag: the fitted drag_coeff switches the KC drag off too
        return {"oscillatory_drag": 0.0, "drag_coeff": float(drag), "added_mass_scale": added}
    return {"wake_drag_coeff": float(WAKE_CONSTANTS[law][0] * factor), "added_mass_scale": added}


def realtime_recordings(law: str, seed: int, truth: dict) -> tuple[list[Recording], list[list[str]]]:
    """Three recordings through the real-time emulator (`featherstar emulate --plant-set
    feather.wake=LAW ...` as a child process, the coefficients hidden), each on a fresh emulator
    so that each starts from rest (the plate wake hardly decays at rest), device-timed
    (`clock=device`: the devices keep time, so a loaded PC loses no samples; their load cell
    integrates, so its samples are interval means, as the offline recordings'). Also each run's
    discard reasons by the bench's rules (a discarded run is still returned: the caller reports it)."""
    runs, reasons = [], []
    options = "&timeout_s=0.3&reconnect_s=3&clock=device"
    for k in range(RUNS):
        emulator = spawn_emulator(plant="fmu", morphology=MORPHOLOGY, noise_N=0.005, seed=100 * seed + k,
                                  start_timeout_s=300, plant_parameters={
                                      "feather.wake": law, **{f"feather.{n}": v for n, v in truth.items()}})
        try:
            run = run_on_bench(SCENE, {"servo": emulator.servo_url + options,
                                       "loadcell": emulator.loadcell_url + options},
                               {**OVERRIDES, **STROKE, "controller.period_s": PERIOD_S, "master.step_s": 0.005,
                                "master.t_end_s": DESIGN["record_s"], "metrics.settle_periods": 0})
        finally:
            emulator.stop()
        runs.append(Recording(f"{law}-s{seed}-realtime{k}", run.time_s, run.angle_rad, run.thrust_N,
                              ("s", "rad", "N"), PERIOD_S))
        reasons.append(discard_reasons(run))
    return runs, reasons


def recordings(law: str, seed: int, truth: dict) -> list[Recording]:
    runs = []
    for k in range(RUNS):
        run = _offline_run(MORPHOLOGY, {**STROKE, "master.t_end_s": DESIGN["record_s"], "metrics.settle_periods": 0}, truth,
                           100 * seed + k, {"wake": law})
        runs.append(Recording(f"{law}-s{seed}-run{k}", run["time_s"], run["angle_rad"], run["thrust_N"],
                              ("s", "rad", "N"), PERIOD_S))
    return runs


def case(law: str, seed: int, forms: tuple[str, ...], realtime: bool = False) -> dict:
    """One law and seed: record (offline, or through the real-time emulator), fit every form, choose."""
    truth = hidden(law, seed)
    started = time.perf_counter()
    discarded: list[list[str]] = []
    if realtime:
        runs, discarded = realtime_recordings(law, seed, truth)
        print(f"    recorded in real time ({time.perf_counter() - started:.0f} s); discard reasons: {discarded}",
              flush=True)
    else:
        runs = recordings(law, seed, truth)
    last = [None]

    def progress(form: str, stage: str, n: int) -> None:
        if (form, stage) != last[0]:
            print(f"    {time.perf_counter() - started:6.0f} s  {form}: {stage}", flush=True)
            last[0] = (form, stage)

    fits, choice, _ = calibrate_forms(runs, SCENE, OVERRIDES, forms, window_s=DESIGN["window_s"], progress=progress,
                                      thrust_samples=THRUST_SAMPLES)
    by_form = {f.form: f for f in fits}
    true_fit = by_form.get(law)
    errors = {} if true_fit is None else {
        n: v / truth[n] - 1.0 for n, v in true_fit.calibration.values.items() if n in truth}
    row = {"law": law, "seed": seed, "hidden": truth, "chosen": choice.chosen, "status": choice.status,
           "tied": list(choice.tied), "reason": choice.reason, "hit": choice.chosen == law,
           "true_form_relative_error": errors,
           "true_form_within_tolerance": bool(errors) and all(abs(e) <= COEFFICIENT_TOLERANCE for e in errors.values()),
           "forms": {f.form: f.as_dict() for f in fits}, "wall_s": round(time.perf_counter() - started, 1),
           **({"recordings": "real-time emulator, device-timed", "discard_reasons": discarded} if realtime else {})}
    print(f"  {law} seed {seed}: chose {choice.chosen or 'undecided'} ({choice.status}); held-out mN "
          + ", ".join(f"{f.form} {f.held_out_rms_N * 1e3:.2f}" for f in fits)
          + "; true form's errors " + ", ".join(f"{n} {e:+.1%}" for n, e in errors.items()), flush=True)
    return row


def realtime_check(seed: int = 0, law: str = "plate") -> dict:
    """One recording through the real-time emulator (child process, the law hidden) against the
    offline recording of the same plant, and the true form's calibration predicting it."""
    truth = hidden(law, seed)
    emulator = spawn_emulator(plant="fmu", morphology=MORPHOLOGY, noise_N=0.005, seed=seed, start_timeout_s=300,
                              plant_parameters={"feather.wake": law, **{f"feather.{k}": v for k, v in truth.items()}})
    try:
        run = run_on_bench(SCENE, _urls(emulator), {**OVERRIDES, **STROKE, "controller.period_s": PERIOD_S,
                                                     "master.step_s": 0.005, "master.t_end_s": DESIGN["record_s"],
                                                     "metrics.settle_periods": 0})
    except BenchFault as exc:
        return {"error": f"bench fault: {exc}"}
    finally:
        emulator.stop()
    live = Recording("realtime", run.time_s, run.angle_rad, run.thrust_N, ("s", "rad", "N"), PERIOD_S)
    offline = recordings(law, seed, truth)[0]
    form = {**OVERRIDES, "feather.wake": law}
    measured_live, predicted = predict(live, SCENE, form, truth, DESIGN["window_s"], THRUST_SAMPLES)
    measured_offline, _ = predict(offline, SCENE, form, truth, DESIGN["window_s"], THRUST_SAMPLES)
    n = min(len(measured_live), len(measured_offline))
    return {"law": law, "seed": seed, "discard_reasons": discard_reasons(run),
            "rms_realtime_minus_offline_N": float(np.sqrt(np.mean((measured_live[:n] - measured_offline[:n]) ** 2))),
            "rms_thrust_N": float(np.sqrt(np.mean(measured_offline**2))),
            "rms_prediction_error_hidden_coefficients_N": float(np.sqrt(np.mean((predicted - measured_live) ** 2)))}


def plot(rows: list[dict], path: Path) -> None:
    laws = [law for law in FORMS if any(r["law"] == law for r in rows)]
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8))
    for i, law in enumerate(laws):
        mine = [r for r in rows if r["law"] == law]
        for j, form in enumerate(FORMS):
            ratios = [r["forms"][form]["held_out_rms_N"] / min(f["held_out_rms_N"] for f in r["forms"].values())
                      for r in mine if form in r["forms"]]
            a.plot([i + (j - 1.5) * 0.18] * len(ratios), ratios, "o", ms=4, color=f"C{j}",
                   label=f"fitted form {form}" if i == 0 else None)
        hits = sum(r["hit"] for r in mine)
        a.text(i, 0.98, f"{hits}/{len(mine)}", ha="center", va="top", fontsize=8, transform=a.get_xaxis_transform())
        for k, r in enumerate(mine):
            for m, (name, e) in enumerate(r["true_form_relative_error"].items()):
                b.plot(i + (m - 0.5) * 0.25, 100 * e, "os"[m % 2], ms=4, color=f"C{m}",
                       label=name.replace("wake_", "").replace("_", " ") if i == 0 and k == 0 else None)
    for ax in (a, b):
        ax.set_xticks(range(len(laws)), [f"true: {law}" for law in laws])
        ax.set_xlabel("the plant's wake model")
    a.set_ylabel("held-out RMS / best form's")
    a.set_title("held-out error of each fitted form (hits/cases at top)", fontsize=9)
    a.legend(fontsize=7)
    b.axhspan(-100 * COEFFICIENT_TOLERANCE, 100 * COEFFICIENT_TOLERANCE, color="0.9")
    b.set_ylabel("true form's fitted / hidden - 1 (%)")
    b.set_title("coefficients of the true form's fit (±15 % band)", fontsize=9)
    b.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    p.add_argument("--quick", action="store_true", help="one seed, laws none and plate, forms none and plate")
    p.add_argument("--seeds", type=int, default=5, help="seeds per law (default: %(default)s)")
    p.add_argument("--laws", default=",".join(FORMS), help="true laws, comma-separated (default: all)")
    p.add_argument("--stroke", choices=sorted(STROKES), default="symmetric",
                   help="stroke of the recordings (default: %(default)s; asymmetric: fast down, slow return)")
    p.add_argument("--periods", type=int, default=1,
                   help="stroke periods recorded and fitted (default: %(default)s; bench/model_form_design.py "
                        "chooses the design)")
    p.add_argument("--design", choices=sorted(DESIGNS), default=None,
                   help="stroke and periods of a bench/model_form_design.py design (instead of --stroke and "
                        "--periods)")
    p.add_argument("--skip-realtime", action="store_true", help="skip the one real-time emulator recording")
    p.add_argument("--out", type=Path, default=Path("docs/results"), help="where the JSON and PNG go")
    p.add_argument("--part", default=None, metavar="NAME",
                   help="write the cases to bench_model_form_calibration_part-NAME.json (run laws in parallel)")
    p.add_argument("--realtime-only", action="store_true", help="only the real-time emulator check, into a part file")
    p.add_argument("--realtime-cases", action="store_true",
                   help="the cases' recordings through the real-time emulator (device-timed, a fresh emulator "
                        "per recording) instead of offline; writes ..._realtime.json")
    p.add_argument("--merge", action="store_true", help="merge the part files in --out into the JSON and PNG")
    args = p.parse_args()
    if args.realtime_only:
        args.out.mkdir(parents=True, exist_ok=True)
        check = realtime_check()
        (args.out / "bench_model_form_calibration_part-realtime.json").write_text(json.dumps(
            {"machine": {"load_average": list(os.getloadavg())}, "cases": [], "realtime_check": check}, indent=2) + "\n")
        print(check)
        return
    if args.periods < 1:
        p.error(f"--periods {args.periods}: at least 1")
    if args.design is not None:
        STROKES[args.design] = DESIGNS[args.design][0]
        args.stroke, args.periods = args.design, DESIGNS[args.design][1]
        stem = f"bench_model_form_calibration_{args.design}"
    else:
        stem = ("bench_model_form_calibration" + ("" if args.stroke == "symmetric" else f"_{args.stroke}")
                + ("" if args.periods == 1 else f"_{args.periods}periods"))
    stem += "_realtime" if args.realtime_cases else ""
    if args.merge:
        merge(args.out, stem)
        return
    STROKE.update(STROKES[args.stroke])
    DESIGN.update(window_s=args.periods * PERIOD_S, record_s=args.periods * PERIOD_S + 0.2)
    laws = ("none", "plate") if args.quick else tuple(args.laws.split(","))
    forms = ("none", "plate") if args.quick else FORMS
    seeds = 1 if args.quick else args.seeds
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / (f"{stem}_part-{args.part}.json" if args.part else f"{stem}{'_quick' if args.quick else ''}.json")
    started = time.perf_counter()
    results = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                           "load_average_at_start": list(os.getloadavg())},
               "setup": {"morphology": MORPHOLOGY, "stroke": {"name": args.stroke, "overrides": STROKE, "period_s": PERIOD_S},
                         "recordings_per_case": RUNS, "periods": args.periods, "window_s": DESIGN["window_s"],
                         "record_s": DESIGN["record_s"], "hidden_ranges": HIDDEN_RANGES,
                         "forms": list(forms), "thrust_samples": THRUST_SAMPLES, "recordings": (
                             "the real-time emulator (featherstar emulate, FMU plant), device-timed, a fresh "
                             "emulator per recording" if args.realtime_cases else "the emulator's FMU plant stepped "
                             "in simulated time as the bench client drives it (bench_calibration._offline_run)")},
               "cases": []}
    for seed in range(seeds):   # seed by seed: a run cut short still has every law
        for law in laws:
            print(f"law {law}, seed {seed} ...", flush=True)
            results["cases"].append(case(law, seed, forms, realtime=args.realtime_cases))
            results["summary"] = summary(results["cases"])
            path.write_text(json.dumps(results, indent=2) + "\n")
    if not (args.skip_realtime or args.quick or args.realtime_cases):
        print("one real-time emulator recording (plate law) ...", flush=True)
        results["realtime_check"] = realtime_check()
        print(f"  {results['realtime_check']}", flush=True)
    results["machine"]["load_average_at_end"] = list(os.getloadavg())
    results["wall_s"] = round(time.perf_counter() - started, 1)
    path.write_text(json.dumps(results, indent=2) + "\n")
    plot(results["cases"], path.with_suffix(".png"))
    for law, s in results["summary"].items():
        print(f"{law}: picked {s['hits']}/{s['cases']}, chose {s['chosen']}, true form's coefficients within "
              f"15 % in {s['coefficients_within_tolerance']}/{s['cases']} (worst {s['worst_coefficient_error']:+.1%})")
    print(f"wrote {path} and {path.with_suffix('.png')} ({results['wall_s']:.0f} s)")


def merge(out: Path, stem: str) -> None:
    parts = sorted(out.glob(f"{stem}_part-*.json"))
    if not parts:
        raise SystemExit(f"no {stem}_part-*.json in {out}")
    loaded = [json.loads(p.read_text()) for p in parts]
    setups = [part["setup"] for part in loaded if "setup" in part]
    cases = sorted((c for part in loaded for c in part["cases"]), key=lambda c: (FORMS.index(c["law"]), c["seed"]))
    results = {"machine": [part["machine"] for part in loaded], "setup": setups[0],
               "parts": [p.name for p in parts], "wall_s": [part.get("wall_s") for part in loaded],
               "cases": cases, "summary": summary(cases),
               **{k: part[k] for part in loaded for k in ("realtime_check",) if k in part}}
    path = out / f"{stem}.json"
    path.write_text(json.dumps(results, indent=2) + "\n")
    plot(cases, path.with_suffix(".png"))
    print(f"wrote {path} and {path.with_suffix('.png')} from {len(parts)} parts")


def summary(rows: list[dict]) -> dict:
    out = {}
    for law in dict.fromkeys(r["law"] for r in rows):
        mine = [r for r in rows if r["law"] == law]
        errors = [e for r in mine for e in r["true_form_relative_error"].values()]
        out[law] = {"cases": len(mine), "hits": sum(r["hit"] for r in mine),
                    "chosen": [r["chosen"] or "undecided" for r in mine],
                    "coefficients_within_tolerance": sum(r["true_form_within_tolerance"] for r in mine),
                    "worst_coefficient_error": max(errors, key=abs) if errors else None}
    return out


if __name__ == "__main__":
    main()
