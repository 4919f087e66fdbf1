"""Model-form calibration: fit each candidate model form to the same recordings, weigh the
evidence, choose one (`featherstar calibrate`).

A form is the feather's wake build option (`none`, the quasi-steady drag, or a wake law of
featherstar.fmu_src.fluid.WAKE_LAWS). Each form's coefficients are fitted as fit.py fits one
structure (scan + least squares); a form's drag coefficient is its own (`drag_coeff` for `none`,
the law's C_0 `wake_drag_coeff` for a wake), so a --fit of either names the form's.

Evidence per form:
- held-out error: leave one recording out, refit on the others (least squares started at the
  fit on all of them: a refit, not a new search), predict the left-out recording's thrust from
  its own recorded root angle; the RMS over every held-out bin, in N. It is what the choice
  rests on: it penalises a form that fits the noise or the wrong shape, without a model of the
  noise.
- information criteria from the fit on all recordings, with Gaussian residuals of unknown
  variance: AIC = n ln(RSS/n) + 2k, BIC = n ln(RSS/n) + k ln n (n binned samples, k fitted
  coefficients; the forms' fixed wake constants are not fitted, so they do not count). BIC is
  the tie-breaker: it is consistent (picks the true form as n grows, where AIC favours the
  larger), and the forms have the same k, so both reduce to the RSS. The bins are not
  independent where the model error dominates (it is smooth in time), so the effective n is
  smaller than n and both criteria overstate the evidence.

Choice (`choose`): the form with the lowest held-out RMS, unless another form is within noise
of it: its held-out squared error exceeds the best's by less than TIE_SIGMAS standard errors
(paired over the same held-out bins, a Diebold–Mariano comparison; optimistic too, the bins
being correlated). Among tied forms the one with the lowest BIC is chosen if it beats each
other tied form by at least BIC_DECISIVE ("strong" on the Kass–Raftery scale); otherwise the
form is `undecided`. A chosen form with a coefficient the recordings do not identify
(featherstar.optimizer.calibration.identify) is `not identified`: no calibration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ...fmu_src.fluid import WAKE_LAWS
from ..errors import OptimizerError
from .fit import DEFAULT_COEFFICIENTS, Calibration, calibrate, coefficient_ranges, feather_block, feather_model, predict
from .identify import unidentified
from .recordings import Recording, check_same_stroke

FORMS = ("none", *WAKE_LAWS)
TIE_SIGMAS = 2.0
BIC_DECISIVE = 6.0
#: The drag coefficient of each kind of form (a --fit of one names the form's own).
DRAG_NAMES = ("drag_coeff", "wake_drag_coeff")
#: The recording that tells the wake laws apart (`featherstar calibrate --recipe`): chosen by
#: bench/model_form_design.py (docs/results/model_form_design.json) for the plain feather on the
#: testbed, as the stroke of the 4-phase family, and number of periods fitted from rest, whose
#: hardest pair of wake laws is furthest apart relative to the load cell's noise (noise-free
#: recordings of each law, every other law fitted to them). One period of the testbed's
#: symmetric stroke leaves relative, self and plate within noise of each other.
DISCRIMINATING_STROKE = {"controller.period_s": 1.0, "controller.amplitude_deg": 150.0, "controller.log10_up_down": 0.6,
                         "controller.log10_hold_up_down": 0.0, "controller.log10_hold_move": -0.3}
DISCRIMINATING_PERIODS = 3
DISCRIMINATING_MORPHOLOGY = "plain"


@dataclass(frozen=True)
class FormFit:
    """One form's calibration and its evidence."""

    form: str
    calibration: Calibration
    held_out_rms_N: float
    held_out_per_run_N: dict[str, float]
    held_out_squared_N2: np.ndarray   # every held-out bin's squared error, recordings in order
    n_samples: int
    rss_N2: float
    unidentified: dict[str, str]
    simulations: int

    @property
    def n_parameters(self) -> int:
        return len(self.calibration.values)

    @property
    def aic(self) -> float:
        return self.n_samples * math.log(self.rss_N2 / self.n_samples) + 2 * self.n_parameters

    @property
    def bic(self) -> float:
        return self.n_samples * math.log(self.rss_N2 / self.n_samples) + self.n_parameters * math.log(self.n_samples)

    def as_dict(self) -> dict[str, Any]:
        c = self.calibration
        return {"coefficients": {n: {"value": v, "sd": c.sd[n], "identified": n not in self.unidentified,
                                     **({"why_not": self.unidentified[n]} if n in self.unidentified else {})}
                                 for n, v in c.values.items()},
                "fixed": c.fixed, "correlation": c.correlation,
                "held_out_rms_N": self.held_out_rms_N, "held_out_per_run_N": self.held_out_per_run_N,
                "rms_residual_N": c.rms_residual_N, "r_squared": c.r_squared,
                "n_samples": self.n_samples, "n_parameters": self.n_parameters, "rss_N2": self.rss_N2,
                "aic": self.aic, "bic": self.bic, "identified": not self.unidentified,
                "simulations": self.simulations}


@dataclass(frozen=True)
class FormChoice:
    """The chosen form (None: undecided), the forms tied with the best held-out one, and why."""

    chosen: str | None
    tied: tuple[str, ...]
    reason: str
    status: str = field(default="calibrated")   # calibrated | not identified | undecided


def usable_recordings(recordings: Sequence[Recording], window_s: float) -> tuple[list[Recording], list[dict[str, str]]]:
    """(kept, refused): a run whose summary says it is incomplete, or shorter than the window, is
    refused (it would fit a transient the others do not have, or nothing), with the reason."""
    kept, refused = [], []
    for r in recordings:
        if r.complete is False:
            refused.append({"run": r.source, "reason": f"incomplete run ({r.incomplete_reason or 'summary.json: complete = false'})"})
        elif r.time_s[-1] < window_s - 1e-9:
            refused.append({"run": r.source, "reason": f"{r.time_s[-1]:.3g} s long, shorter than the fit window ({window_s:g} s)"})
        else:
            kept.append(r)
    return kept, refused


def form_fit(form: str, model, fit: Mapping[str, tuple[float, float] | None] | None) -> dict[str, tuple[float, float] | None]:
    """The coefficients to fit for `form`: `fit` (default fit.py's DEFAULT_COEFFICIENTS that the
    feather has), a drag coefficient named for another form (DRAG_NAMES) being the form's own."""
    own = {p.name for p in model.parameters}
    mine = "drag_coeff" if form == "none" else "wake_drag_coeff"
    if fit is None:
        fit = {name: None for name in DEFAULT_COEFFICIENTS if name in own or name in DRAG_NAMES}
    # another form's drag coefficient has another scale (a wake's C_0 is ~6): its own physical range
    return {(mine if name in DRAG_NAMES else name): (bounds if name in own else None) for name, bounds in fit.items()}


def fit_form(form: str, recordings: Sequence[Recording], scene: str, overrides: Mapping[str, Any],
             fit: Mapping[str, tuple[float, float] | None] | None, window_s: float,
             progress: Callable[[str, str, int], None] | None = None, thrust_samples: str = "instant") -> FormFit:
    """Fit `form` on all recordings, then each left out in turn (see the module docstring)."""
    form_overrides = {**overrides, "feather.wake": form}
    names = form_fit(form, feather_model(feather_block(scene), form_overrides), fit)

    def tick(stage: str) -> Callable[[int], None] | None:
        return None if progress is None else (lambda n: progress(form, stage, n))

    full = calibrate(recordings, scene, form_overrides, names, window_s=window_s, progress=tick("fit on all runs"),
                     require_sd=False, thrust_samples=thrust_samples)
    simulations = full.evaluations
    squared, per_run = [], {}
    for i, left_out in enumerate(recordings):
        others = [r for j, r in enumerate(recordings) if j != i]
        refit = calibrate(others, scene, form_overrides, names, window_s=window_s, start=full.values,
                          progress=tick(f"held out {left_out.source}"), require_sd=False, thrust_samples=thrust_samples)
        measured, simulated = predict(left_out, scene, form_overrides, {**refit.fixed, **refit.values}, window_s,
                                      thrust_samples)
        simulations += refit.evaluations + 1
        errors2 = (simulated - measured) ** 2
        squared.append(errors2)
        per_run[left_out.source] = float(np.sqrt(np.mean(errors2)))
    held_out = np.concatenate(squared)
    n = int(full.measured_N.size)
    return FormFit(form, full, float(np.sqrt(np.mean(held_out))), per_run, held_out, n,
                   float(full.rms_residual_N**2 * n), unidentified(full), simulations)


def choose(fits: Sequence[FormFit]) -> FormChoice:
    """The rule of the module docstring."""
    best = min(fits, key=lambda f: f.held_out_rms_N)
    tied = [best]
    for f in fits:
        if f is best:
            continue
        d = f.held_out_squared_N2 - best.held_out_squared_N2
        se = float(np.std(d, ddof=1) / math.sqrt(d.size)) if d.size > 1 else math.inf
        if not float(np.mean(d)) > TIE_SIGMAS * se:
            tied.append(f)
    names = tuple(f.form for f in tied)
    if len(tied) == 1:
        chosen, reason = best, (f"lowest held-out RMS ({best.held_out_rms_N * 1e3:.2f} mN), every other form "
                                f"more than {TIE_SIGMAS:g} standard errors worse")
    else:
        by_bic = sorted(tied, key=lambda f: f.bic)
        margin = by_bic[1].bic - by_bic[0].bic
        if margin >= BIC_DECISIVE:
            chosen = by_bic[0]
            reason = (f"held-out RMS within noise of each other for {', '.join(names)}; BIC tie-break: "
                      f"{chosen.form} lower by {margin:.1f} (>= {BIC_DECISIVE:g})")
        else:
            hint = ("; recordings of the stroke `featherstar calibrate --recipe` prints tell the wake laws apart"
                    if sum(f.form != "none" for f in tied) > 1 else "")
            return FormChoice(None, names, f"held-out RMS within noise of each other for {', '.join(names)} "
                                           f"and BIC within {BIC_DECISIVE:g} ({margin:.1f}): the recordings do "
                                           f"not decide the model form{hint}", "undecided")
    if chosen.unidentified:
        return FormChoice(chosen.form, names, reason + f"; but the recordings do not identify "
                          f"{', '.join(chosen.unidentified)}", "not identified")
    return FormChoice(chosen.form, names, reason)


def fit_window_s(recordings: Sequence[Recording], window_s: float | None = None, periods: int | None = None) -> float:
    """The fit window: `window_s`, else `periods` (default 1) stroke periods of the runs (their
    summary.json's period, which must be one). Several periods tell the wake laws apart where one
    does not (DISCRIMINATING_DESIGN); the plain feather is not chaotic, so they can be matched
    sample by sample (a flapped feather's later periods may not be: fit.py)."""
    if window_s is not None and periods is not None:
        raise OptimizerError("--window-s and --periods both set the fit window: give one")
    if periods is not None and not (isinstance(periods, int) and periods >= 1):
        raise OptimizerError(f"--periods {periods} must be a whole number of stroke periods, at least 1")
    if window_s is None:
        known = {r.period_s for r in recordings}
        if None in known or len(known) != 1:
            raise OptimizerError("the stroke period of the runs is unknown (no summary.json beside them) or not "
                                 "one: give --window-s, e.g. the stroke period times the periods to fit")
        window_s = known.pop() * (1 if periods is None else periods)
    if not (math.isfinite(window_s) and window_s > 0):
        raise OptimizerError(f"--window-s {window_s} must be a positive number of seconds")
    return float(window_s)


def calibrate_forms(recordings: Sequence[Recording], scene: str, overrides: Mapping[str, Any],
                    forms: Sequence[str] = FORMS, fit: Mapping[str, tuple[float, float] | None] | None = None, *,
                    window_s: float | None = None, periods: int | None = None,
                    progress: Callable[[str, str, int], None] | None = None, thrust_samples: str = "instant"
                    ) -> tuple[list[FormFit], FormChoice, list[dict[str, str]]]:
    """(each form's fit, the choice, the refused recordings) for these recordings; the fit window
    is `window_s`, or `periods` stroke periods of the runs (default one: `fit_window_s`)."""
    unknown = [f for f in forms if f not in FORMS]
    if unknown or not forms:
        raise OptimizerError(f"--forms {','.join(forms)}: valid forms are {', '.join(FORMS)}")
    window_s = fit_window_s(recordings, window_s, periods)
    kept, refused = usable_recordings(recordings, window_s)
    if kept:
        check_same_stroke(kept, window_s)
    block = feather_block(scene)
    for form in forms:   # every form's coefficients and ranges checked before any simulation
        model = feather_model(block, {**overrides, "feather.wake": form})
        coefficient_ranges(model, form_fit(form, model, fit))
    if len(kept) < 2:
        why = "; ".join(f"{r['run']}: {r['reason']}" for r in refused)
        raise OptimizerError(f"model-form calibration needs at least 2 usable runs (one is held out), "
                             f"{len(kept)} left{' (refused: ' + why + ')' if why else ''}")
    fits = [fit_form(form, kept, scene, overrides, fit, window_s, progress, thrust_samples) for form in forms]
    return fits, choose(fits), refused


def recipe(scene: str = "testbed") -> list[str]:
    """The commands that record and calibrate the discriminating design (DISCRIMINATING_STROKE
    over DISCRIMINATING_PERIODS periods, recorded 0.2 s longer, three runs each from rest)."""
    period_s = DISCRIMINATING_STROKE["controller.period_s"]
    record_s = DISCRIMINATING_PERIODS * period_s + 0.2
    stroke = " ".join(f"{k}={v:g}" for k, v in DISCRIMINATING_STROKE.items())
    return [f"# the stroke that tells the wake laws apart (measured for the {DISCRIMINATING_MORPHOLOGY} feather: "
            "bench/model_form_design.py, docs/bench-loop.md); three runs, each from rest:",
            "# (on a busy PC give both URLs clock=device, docs/hil.md; an integrating load cell, such as the "
            "emulator's, wants calibrate --thrust-samples interval-mean: the real-time check used both)",
            *(f"featherstar run {scene} --hardware servo=URL --hardware loadcell=URL --set feather.morphology="
              f"{DISCRIMINATING_MORPHOLOGY} {stroke} master.t_end_s={record_s:g} metrics.settle_periods=0 "
              f"--out runs/r{k}" for k in (1, 2, 3)),
            f"featherstar calibrate runs/r1 runs/r2 runs/r3 --scene {scene} --set feather.morphology="
            f"{DISCRIMINATING_MORPHOLOGY} --periods {DISCRIMINATING_PERIODS} --out runs/cal"]


def evidence_table(fits: Sequence[FormFit]) -> list[str]:
    """One line per form: held-out RMS, AIC, BIC, fitted coefficients, identification."""
    best_bic = min(f.bic for f in fits)
    lines = []
    for f in fits:
        coefficients = ", ".join(f"{n} {v:.4g}±{f.calibration.sd[n]:.2g}{'?' if n in f.unidentified else ''}"
                                 for n, v in f.calibration.values.items())
        lines.append(f"  {f.form:9s} held-out rms {f.held_out_rms_N * 1e3:7.3f} mN  fit rms "
                     f"{f.calibration.rms_residual_N * 1e3:7.3f} mN  AIC {f.aic:8.1f}  BIC {f.bic:8.1f} "
                     f"(Δ {f.bic - best_bic:5.1f})  {coefficients}"
                     + ("" if not f.unidentified else "  NOT IDENTIFIED: " + ", ".join(f.unidentified)))
    return lines

