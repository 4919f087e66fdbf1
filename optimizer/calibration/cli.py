"""`featherstar calibrate RUN... --scene SCENE`: fit each model form's feather coefficients to
recorded load-cell runs, weigh the evidence, choose a form.

Writes DIR/calibration.json (every form's coefficients with sd and identification, held-out
RMS, AIC and BIC; the chosen form and the rule; the refused runs; at the top level the chosen
form's parameter set and fit quality), and, when the result is a calibration (a form chosen,
every coefficient identified), DIR/set.txt (the same as `--set` arguments for run, optimize and
sweep, the wake build option included), DIR/feather-parameters.toml (the feather block's
`parameters` line and its `wake` option for a scene file); DIR/fit.png (measured and fitted
thrust per run). The method: featherstar.optimizer.calibration.forms and .fit.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Sequence

from ...fmu_src.catalog import build_options
from ..errors import OptimizerError
from ..log import dumps
from ..options import command, number, one_line_errors, out_dir
from ..postprocess import optional
from .fit import BIN_S, DEFAULT_COEFFICIENTS, THRUST_SAMPLES, Calibration, feather_block
from .forms import (BIC_DECISIVE, FORMS, TIE_SIGMAS, FormChoice, FormFit, calibrate_forms, evidence_table,
                    recipe)
from .identify import MAX_CORRELATION, MAX_RELATIVE_SD
from .recordings import read_recording

#: Exit status when no calibration is written: the form is undecided or a coefficient not identified.
NOT_A_CALIBRATION = 3


def _fit(text: str) -> tuple[str, tuple[float, float] | None]:
    name, sep, pair = text.partition("=")
    if not sep:
        return name.strip(), None
    low, comma, high = pair.partition(",")
    try:
        if not comma:
            raise ValueError
        return name.strip(), (float(low), float(high))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--fit wants NAME or NAME=LOW,HIGH (e.g. drag_coeff=0.5,3), got {text!r}") from None


def _periods(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants a whole number of stroke periods, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"wants at least 1 stroke period, got {value}")
    return value


def register_calibrate(subparsers: argparse._SubParsersAction, override_type) -> None:
    cal = subparsers.add_parser(
        "calibrate", help="fit and compare feather model forms (wake laws) and coefficients on recorded load-cell runs",
        description="Fit coefficients of a scene's feather to recorded runs, for each model form (wake law): "
                    "`featherstar run --hardware --out DIR` directories, or CSVs with time, root angle and thrust "
                    "columns. The runs must repeat one stroke, from rest; a run whose summary says it is incomplete, "
                    "or shorter than the window, is refused and named. The simulated feather's root follows the "
                    f"recorded angle; the fit matches the thrust averaged over {BIN_S * 1e3:g} ms bins over the first "
                    "window (docs/bench-loop.md says why). A coefficient with sd above "
                    f"{MAX_RELATIVE_SD:.0%} of its value or |correlation| above {MAX_CORRELATION:g} is not identified. "
                    f"Exit status {NOT_A_CALIBRATION} (and no set.txt) when the form is undecided or the chosen "
                    "form has a coefficient the runs do not identify.")
    one_line_errors(cal)
    cal.add_argument("runs", nargs="*", type=Path, metavar="RUN", help="run directory or CSV (repeatable; at least one)")
    cal.add_argument("--recipe", action="store_true",
                     help="print the commands that record runs telling the wake laws apart (a stroke and a number "
                          "of periods, chosen by bench/model_form_design.py) and calibrate them; nothing is fitted")
    cal.add_argument("--scene", default="testbed", help="scene whose feather block is calibrated (default testbed)")
    cal.add_argument("--set", dest="overrides", metavar="KEY=VALUE", type=override_type, action="extend", nargs="+",
                     default=[], help="scene overrides, one or more per --set, e.g. feather.morphology=spanwise "
                     "(the feather the bench has)")
    cal.add_argument("--fit", type=_fit, action="append", default=[], metavar="NAME[=LOW,HIGH]",
                     help=f"coefficient to fit, within its physical range or a narrower one (default: "
                          f"{', '.join(DEFAULT_COEFFICIENTS)}, those the feather has; under a wake law drag_coeff "
                          "is the law's C_0, wake_drag_coeff, fitted in its own physical range)")
    cal.add_argument("--forms", default=None, metavar="FORM,...",
                     help=f"model forms (the feather's wake build option) to fit and compare (default: all, "
                          f"{','.join(FORMS)}; a --set feather.wake=FORM fits that one). Each is judged by its "
                          "held-out error (each run left out in turn, predicted from a fit on the others) with "
                          f"BIC as tie-breaker; forms within noise ({TIE_SIGMAS:g} standard errors) and BIC within "
                          f"{BIC_DECISIVE:g} leave the form undecided")
    cal.add_argument("--thrust-samples", choices=THRUST_SAMPLES, default="instant",
                     help="what a recorded thrust sample is: the force at its time stamp (default) or the mean "
                          "force over the interval before it (interval-mean: an integrating load cell, such as "
                          "the emulator's; then it is compared at the interval's middle)")
    cal.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    window = cal.add_mutually_exclusive_group()
    window.add_argument("--window-s", type=number(above=0.0), default=None, metavar="S",
                        help="fit the first S seconds of each run (default: one stroke period, from summary.json)")
    window.add_argument("--periods", type=_periods, default=None, metavar="N",
                        help="fit the first N stroke periods of each run (period from summary.json; default 1). "
                             "One period from rest does not tell the wake laws apart; see --recipe")
    cal.add_argument("--time-column", default=None)
    cal.add_argument("--angle-column", default=None)
    cal.add_argument("--thrust-column", default=None)
    cal.add_argument("--out", type=out_dir, default="runs/calibration", help="output directory")
    cal.set_defaults(func=command("featherstar calibrate", _calibrate_command))


class _Progress:
    """One line per form and fit; on a terminal the line counts the simulations as they run."""

    def __init__(self, forms: Sequence[str]) -> None:
        self.forms, self.stage, self.tty = list(forms), None, sys.stdout.isatty()

    def __call__(self, form: str, stage: str, simulations: int) -> None:
        text = f"  [{self.forms.index(form) + 1}/{len(self.forms)}] {form}: {stage}"
        if (form, stage) != self.stage:
            if self.tty and self.stage is not None:
                print(flush=True)
            self.stage = (form, stage)
            if not self.tty:
                print(text + " ...", flush=True)
        if self.tty:
            print(f"\r{text}: {simulations} simulations", end="", flush=True)

    def done(self) -> None:
        if self.tty and self.stage is not None:
            print(flush=True)


def _forms(args: argparse.Namespace, overrides: dict) -> tuple[str, ...]:
    if args.forms is not None:
        if "feather.wake" in overrides:
            raise OptimizerError("--forms and --set feather.wake both choose the model form: give one")
        forms = tuple(f.strip() for f in args.forms.split(",") if f.strip())
        bad = [f for f in forms if f not in FORMS] or ([] if forms else [args.forms])
        if bad or len(set(forms)) != len(forms):
            raise OptimizerError(f"--forms {args.forms}: valid forms are {', '.join(FORMS)} (each once)")
        return forms
    if "feather.wake" in overrides:
        return (str(overrides.pop("feather.wake")),)
    return FORMS


def _calibrate_command(args: argparse.Namespace) -> int:
    if args.recipe:
        if args.runs:
            raise OptimizerError("--recipe prints how to record runs and fits nothing: give it without RUN")
        print("\n".join(recipe(args.scene)))
        return 0
    if not args.runs:
        raise OptimizerError("calibrate needs at least one RUN (a run directory or CSV), or --recipe")
    recordings = [read_recording(path, time_column=args.time_column, angle_column=args.angle_column,
                                 thrust_column=args.thrust_column) for path in args.runs]
    overrides = dict(args.overrides)
    stray = [k for k in overrides if not k.startswith("feather.")]
    if stray:
        raise OptimizerError(f"--set {stray[0]}: calibrate simulates the feather alone; only feather.* overrides apply")
    forms = _forms(args, overrides)
    if forms[0] not in FORMS:
        raise OptimizerError(f"--set feather.wake={forms[0]}: valid forms are {', '.join(FORMS)}")
    fit = dict(args.fit) or None
    progress = None if args.quiet else _Progress(forms)
    print(f"calibrating the feather of {args.scene} on {len(recordings)} runs, forms {', '.join(forms)} "
          f"(each: a fit on all runs, then one per run left out) ...", flush=True)
    try:
        fits, choice, refused = calibrate_forms(recordings, args.scene, overrides, forms, fit,
                                                window_s=args.window_s, periods=args.periods, progress=progress,
                                                thrust_samples=args.thrust_samples)
    finally:
        if progress is not None:
            progress.done()
    for r in refused:
        print(f"refused {r['run']}: {r['reason']}")
    chosen = next((f for f in fits if f.form == choice.chosen), None)
    shown = chosen or min(fits, key=lambda f: f.held_out_rms_N)
    paths = write_calibration(fits, choice, args.out, runs=[r.source for r in recordings], scene=args.scene,
                              overrides=overrides, refused=refused, thrust_samples=args.thrust_samples)
    # The figure is optional post-processing: the calibration is already on disk.
    runs = [r.source for r in recordings if r.source not in {x["run"] for x in refused}]
    if optional("fit.png", _fit_figure, shown.calibration, runs, args.out / "fit.png", shown.form) is not None:
        paths.append(args.out / "fit.png")
    print("evidence per form (held-out: each run predicted from a fit on the others; '?': not identified):")
    print("\n".join(evidence_table(fits)))
    print(f"form: {choice.chosen or 'undecided'} ({choice.reason})")
    if chosen is not None:
        for c in chosen.calibration.coefficients:
            print(f"  {c.name:28s} {chosen.calibration.values[c.name]:.4g} ± {chosen.calibration.sd[c.name]:.2g} {c.unit}"
                  + (f"  NOT IDENTIFIED: {chosen.unidentified[c.name]}" if c.name in chosen.unidentified else ""))
    print(f"wrote {', '.join(str(p) for p in paths)}")
    if choice.status != "calibrated":
        print(f"NOT A CALIBRATION ({choice.status}): nothing written as a parameter set")
        return NOT_A_CALIBRATION
    print(f"use it: {set_arguments(chosen)}")
    return 0


def set_arguments(fit: FormFit) -> str:
    return " ".join([f"--set feather.wake={fit.form}"]
                    + [f"--set {k}={v:.6g}" for k, v in fit.calibration.parameter_set().items()])


def write_calibration(fits: Sequence[FormFit], choice: FormChoice, out: Path, *, runs: list[str], scene: str,
                      overrides: dict, refused: list[dict[str, str]] = (), thrust_samples: str = "instant") -> list[Path]:
    """calibration.json; set.txt and feather-parameters.toml when the choice is a calibration (the
    figure is drawn separately)."""
    out.mkdir(parents=True, exist_ok=True)
    chosen = next((f for f in fits if f.form == choice.chosen), None)
    report = {"status": choice.status, "chosen_form": choice.chosen or "undecided",
              "choice": {"reason": choice.reason, "tied": list(choice.tied),
                         "rule": f"lowest held-out RMS; forms within {TIE_SIGMAS:g} standard errors of it (paired "
                                 f"over the held-out bins) tied, then the lowest BIC if lower by >= {BIC_DECISIVE:g}, "
                                 "else undecided; a chosen form with an unidentified coefficient is no calibration",
                         "identification": f"sd <= {MAX_RELATIVE_SD:g} x value and |correlation| <= {MAX_CORRELATION:g}"},
              "information_criteria": "AIC = n ln(RSS/n) + 2k, BIC = n ln(RSS/n) + k ln n over the binned samples; "
                                      "the bins are correlated where the model error dominates, so both overstate the evidence",
              "forms": {f.form: f.as_dict() for f in fits},
              **(chosen.calibration.as_dict() if chosen is not None else {}),
              "scene": scene, "overrides": overrides, "runs": runs, "thrust_samples": thrust_samples, "refused_runs": list(refused),
              "window_s": fits[0].calibration.window_s}
    paths = [out / "calibration.json"]
    paths[0].write_text(json.dumps(json.loads(dumps(report)), indent=2) + "\n")
    for stale in ("set.txt", "feather-parameters.toml"):   # a parameter set of an earlier run must not stay
        (out / stale).unlink(missing_ok=True)
    if choice.status != "calibrated":
        return paths
    paths += [out / "set.txt", out / "feather-parameters.toml"]
    paths[1].write_text(set_arguments(chosen) + "\n")
    # The scene's own feather parameters, the feather.* overrides, then the calibrated ones; a
    # parameter the chosen form lacks (drag_coeff under a wake law) is dropped.
    names = {c.name for c in chosen.calibration.coefficients} | set(chosen.calibration.fixed)
    merged = {**feather_block(scene).get("parameters", {}),
              **{k.split(".", 1)[1]: v for k, v in overrides.items() if k.startswith("feather.")
                 and k.split(".", 1)[1] not in build_options("feather")},
              **{k.split(".", 1)[1]: v for k, v in chosen.calibration.parameter_set().items()}}
    if chosen.form != "none":
        merged = {k: v for k, v in merged.items() if k not in ("drag_coeff", "oscillatory_drag", "stroke_amplitude_rad")
                  or k in names}
    inline = ", ".join(f"{k} = {v:.6g}" if isinstance(v, (int, float)) else f'{k} = "{v}"' for k, v in merged.items())
    paths[2].write_text(f"# calibrated feather of scene '{scene}' ({', '.join(Path(r).name for r in runs)}), "
                        f"model form wake = {chosen.form}:\n"
                        "# in the scene's [blocks.feather] table, set the build option and replace the parameters line:\n"
                        f"# options = {{ wake = \"{chosen.form}\" }}   (with the table's other options)\n"
                        f"parameters = {{ {inline} }}\n")
    return paths


def _fit_figure(result: Calibration, runs: list[str], path: Path, form: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ...cosim.plotstyle import save_figure

    fig, ax = plt.subplots(figsize=(7, 3.2))
    for k, run in enumerate(runs):
        ax.plot(result.bin_times_s, result.measured_N[k] * 1e3, ".", ms=3, color=f"C{k}", label=f"measured {Path(run).name}")
    ax.plot(result.bin_times_s, result.simulated_N[0] * 1e3, "-", color="k", lw=1.2, label=f"calibrated simulation (wake = {form})")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"thrust, {BIN_S * 1e3:g} ms means (mN)")
    ax.set_title(f"calibration: rms residual {result.rms_residual_N * 1e3:.1f} mN, R² {result.r_squared:.3f}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)
