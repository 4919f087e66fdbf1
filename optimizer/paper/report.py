"""The claims table and the markdown of `featherstar paper` (featherstar.optimizer.paper.paper).

Each claim is a number the paper reports, the simulated counterpart, an agreement band written
down before looking at the result (stated in the table, so a reader can judge it), and a note.
Where the model is known not to reproduce a claim, the note says so and why (docs/model.md, the
strict xfails in the tests); the model is never tuned here to force agreement.
"""
from __future__ import annotations

import datetime
import math
from pathlib import Path
from typing import Any, Mapping

INF = math.inf


def _get(mapping: Mapping, *keys: str, default: Any = math.nan) -> Any:
    for key in keys:
        if not isinstance(mapping, Mapping) or key not in mapping:
            return default
        mapping = mapping[key]
    return mapping


def _finite(*values: float) -> bool:
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


def _claim(id_: str, claim: str, source: str, paper: str, value: float, unit: str, band: tuple[float, float],
           note: str, text: str | None = None, agrees: bool | None = None) -> dict:
    if agrees is None and _finite(value):
        agrees = band[0] <= value <= band[1]
    shown = text or (f"{value:.2f}{' ' + unit if unit else ''}" if _finite(value) else "n/a (failed)")
    return {"id": id_, "claim": claim, "source": source, "paper": paper, "simulated": value, "simulated_text": shown,
            "unit": unit, "band": list(band), "agrees": agrees, "note": note}


def _stroke_text(stroke: Mapping | None) -> str:
    if not stroke:
        return "?"
    return (f"up {stroke['t_up_s']:.2f} s, hold {stroke['t_hold_up_s']:.2f} s, down {stroke['t_down_s']:.2f} s, "
            f"hold {stroke['t_hold_down_s']:.2f} s")


def claims(data: Mapping) -> list[dict]:
    sym, studies, robot = data["symmetric"], data["studies"], data["robot"]
    rows = []

    def sym_tr(family: str) -> float:
        return _get(sym, family, "thrust_ratio")

    def sym_text(family: str) -> str:
        run = sym.get(family, {})
        return f"{run['thrust_ratio']:.2f} ± {run['thrust_ratio_sd']:.2f}" if "thrust_ratio" in run else "n/a (failed)"

    rows.append(_claim("plain_symmetric", "plain feather, symmetric stroke: thrust is symmetric", "Sec. III-A, Fig. 5",
                       "TR ≈ 1", sym_tr("plain"), "", (0.8, 1.25), "Mean ± sd over the load-cell sets.",
                       sym_text("plain")))
    chord = sym_tr("chordwise")
    rows.append(_claim(
        "chordwise_symmetric", "chordwise flaps (WR 7.5), symmetric stroke: positive thrust almost double the negative",
        "Sec. III-A, Fig. 5", "TR ≈ 2", chord, "", (1.5, 3.0),
        "Directional as in the paper, but stronger than its ≈ 2: the model's chordwise feather is more asymmetric "
        "than the paper's." if _finite(chord) and chord > 2.5 else "",
        sym_text("chordwise")))
    span = sym.get("spanwise", {})
    low, high = span.get("peak_thrust_N", [math.nan, math.nan])
    rows.append(_claim(
        "spanwise_symmetric", "spanwise flaps (LR 2), symmetric stroke: positive thrust almost double the negative",
        "Sec. III-A, Fig. 5", "TR ≈ 2", sym_tr("spanwise"), "", (1.5, 3.0),
        "The root part is held by its support, the outer part is a one-way flap (docs/model.md, spanwise "
        f"mechanism): it folds to {span.get('max_fold_deg') or math.nan:.0f}° on the upstroke and lies on its stop "
        f"on the downstroke; thrust swings between {1e3 * low:.0f} and {1e3 * high:.0f} mN around a mean of "
        f"{1e3 * span.get('mean_thrust_N', math.nan):.1f} mN.", sym_text("spanwise")))

    def optimized(family: str, paper: str, band: tuple[float, float], gap: str) -> dict:
        study = studies.get(f"{family}-max", {})
        value = study.get("estimated_thrust_ratio", math.nan)
        iterations = len(study.get("evaluations", []))
        note = (f"Estimated TR (best posterior mean, as the paper's Fig. 6) after {iterations} iterations; "
                f"validated {_get(study, 'summary', 'thrust_ratio'):.2f} ± {_get(study, 'summary', 'thrust_ratio_sd'):.2f}"
                f" vs baseline {_get(study, 'summary', 'baseline_thrust_ratio'):.2f}; stroke: {_stroke_text(study.get('stroke'))}.")
        if iterations and iterations < 20:
            note += f" Reduced budget ({iterations} of the paper's 30 iterations; it converged by 20)."
        if _finite(value) and not band[0] <= value <= band[1]:
            note += " " + gap
        return _claim(f"{family}_optimized", f"{family} flaps, optimized stroke at 1.5 s: stable estimated TR",
                      "Sec. III-B, Fig. 6", paper, value, "", band, note)

    rows.append(optimized("chordwise", "TR ≈ 4", (3.0, 5.5),
                          "Below the band: more iterations (full mode) usually lift the estimate."))
    rows.append(optimized("spanwise", "TR ≈ 2.5", (2.0, 3.2),
                          "Outside the band: more iterations (full mode) move the estimate; see the study's "
                          "progress figure."))
    plain = studies.get("plain-max", {})
    plain_tr = _get(plain, "summary", "thrust_ratio")
    plain_note = (f"Validated best TR, mean thrust {1e3 * _get(plain, 'summary', 'mean_thrust_N'):.1f} mN; stroke: "
                  f"{_stroke_text(plain.get('stroke'))}.")
    if _finite(plain_tr) and plain_tr > 1.15:
        plain_note += (" Known model gap, not forced: quasi-steady drag grows as v², so a slow upstroke and a fast "
                       "downstroke give net thrust (a rigid plate's drag-only TR is exactly t_up/t_down); the "
                       "paper's plain feather does not show it. The default model has no wake: the water the fast "
                       "stroke sets moving, which the next stroke meets; under the feather's `wake` option (three "
                       "laws fitted to plate data) the slow-return stroke's TR falls from 1.30 to 0.98-1.02, the "
                       "law undecided by those data (docs/model.md; strict xfail in "
                       "tests/optimizer/test_physics_acceptance.py).")
    rows.append(_claim("plain_optimized", "plain feather, best controller: no useful asymmetric thrust",
                       "Sec. III-D, Fig. 8", "TR ≲ 1", plain_tr, "", (0.0, 1.15), plain_note))
    chord_best = _get(studies, "chordwise-max", "summary", "thrust_ratio")
    plain_sym = sym_tr("plain")
    ratio = chord_best / plain_tr if _finite(chord_best, plain_tr) else math.nan
    useful_note = ("Read as validated TR, best chordwise / best plain (each with its own optimized stroke); the paper "
                   "does not define 'useful thrust'. Against the plain feather's symmetric-stroke TR the ratio is "
                   f"{chord_best / plain_sym if _finite(chord_best, plain_sym) else math.nan:.2f}.")
    if _finite(ratio, plain_tr) and 2.0 <= ratio <= 3.2 and plain_tr > 1.15:
        useful_note += (" The agreement is partly fortuitous: the plain feather's optimized TR is itself too high "
                        "(row 6), and the chordwise one above the paper's.")
    rows.append(_claim("useful_thrust", "co-optimized asymmetric feather vs the symmetric (plain) one: useful thrust",
                       "Abstract", "2.5 ×", ratio, "×", (2.0, 3.2), useful_note))

    flapped = [studies.get(f"{f}-max", {}).get("summary", {}) for f in ("chordwise", "spanwise")]
    best_trs = [s.get("thrust_ratio", math.nan) for s in flapped]
    base_trs = [s.get("baseline_thrust_ratio", math.nan) for s in flapped]
    known = _finite(*best_trs, *base_trs)
    rows.append(_claim(
        "flapped_best", "flapped feathers, best controller: TR > 2 and above the symmetric baseline",
        "Sec. III-D, Fig. 8", "TR > 2", min(best_trs) if known else math.nan, "", (2.0, INF),
        f"Best vs baseline: chordwise {best_trs[0]:.2f} vs {base_trs[0]:.2f}, spanwise {best_trs[1]:.2f} vs "
        f"{base_trs[1]:.2f} (the smaller best is shown; agreement also needs best > baseline for both)."
        + (" Spanwise below 2 (row 5)." if _finite(best_trs[1]) and best_trs[1] <= 2.0 else ""),
        text=f"min {min(best_trs):.2f}" if _finite(*best_trs) else None,
        agrees=(min(best_trs) > 2.0 and all(b > a for b, a in zip(best_trs, base_trs))) if known else None))
    worst = [_get(studies, f"{f}-min", "summary", "thrust_ratio") for f in ("chordwise", "spanwise")]
    rows.append(_claim(
        "flapped_worst", "flapped feathers, worst controller: still more positive than negative thrust",
        "Sec. III-D, Fig. 8", "TR > 1", min(worst) if _finite(*worst) else math.nan, "", (1.0, INF),
        f"Worst TR: chordwise {worst[0]:.2f}, spanwise {worst[1]:.2f}."
        + (" Spanwise below 1." if _finite(worst[1]) and worst[1] <= 1.0 else ""),
        text=f"min {min(worst):.2f}" if _finite(*worst) else None))

    def speeds(family: str) -> dict[str, float]:
        return {c: 1e2 * robot.get(f"{family}-{c}", {}).get("mean_speed_m_s", math.nan)
                for c in ("best", "baseline", "worst")}

    listing = lambda s: ", ".join(f"{c} {v:.2f}" for c, v in s.items())  # noqa: E731
    chord_speeds, plain_speeds = speeds("chordwise"), speeds("plain")
    top = max((v for v in chord_speeds.values() if _finite(v)), default=math.nan)
    rows.append(_claim(
        "robot_chordwise", "robot with chordwise flaps: maximum speed", "Sec. III-E, Fig. 9", "≈ 2.5 cm/s", top,
        "cm/s", (1.5, 3.5),
        f"Highest mean speed over the controllers (cm/s: {listing(chord_speeds)}). "
        + ("The robot's mass, drag and rail friction are estimates (docs/model.md, Robot: the paper gives no robot "
           "parameters), so its absolute speed is not a prediction; signs and orderings are." if _finite(top)
           and not 1.5 <= top <= 3.5 else "")))
    fastest_plain = max((v for v in plain_speeds.values() if _finite(v)), default=math.nan)
    rows.append(_claim(
        "robot_plain", "robot with plain feathers: no forward motion", "Abstract, Sec. III-E, Fig. 9",
        "≈ 0 cm/s", fastest_plain, "cm/s", (-INF, 0.25),
        f"Fastest plain-feather mean speed over the controllers (cm/s: {listing(plain_speeds)})."
        + (" It moves forward with the optimized stroke: the plain-feather gap above carried to the robot."
           if _finite(fastest_plain) and fastest_plain > 0.25 else "")))
    margins = {f: speeds(f)["best"] - speeds(f)["worst"] for f in ("plain", "chordwise", "spanwise")}
    rows.append(_claim(
        "robot_best_worst", "robot: the best controller outperforms the worst, in all cases", "Sec. III-E, Fig. 9",
        "best > worst", min(margins.values()) if _finite(*margins.values()) else math.nan, "cm/s", (0.0, INF),
        "Smallest best − worst mean-speed difference; per feather (cm/s): "
        + ", ".join(f"{f} {v:+.2f}" for f, v in margins.items()) + "."))
    return rows


HOW_TO_READ = """\
Each section below redoes one figure of the paper in simulation: the same feathers (plain,
chordwise flaps WR 7.5, spanwise flaps LR 2; 115 × 75 mm unfolded), the same 60° four-phase
stroke, the same thrust ratio TR = ∫T⁺dt / ∫|T⁻|dt (Eq. 3) and mean thrust (Eq. 2), read through a
simulated 80 Hz load cell with 5.9 mN noise, and the same Bayesian optimizer (EI-plus, exploration
ratio 0.6). Figures 5–8 come from the load-cell test-bed scene (servo + feather), Fig. 3 from the
kinematic scene (ideal root motion, as the paper's sweep), Fig. 9 from the robot scene (servo,
four-bar, two feathers, body on a rail) driven with the controllers found on the test bed. The
table puts every number the paper reports beside its simulated counterpart. "agrees" means the
simulated value lies in the band shown, fixed in the code before the run: the band is there so
you can judge the verdict, not only read it. A "no" is a finding, not a bug: where the model is
known not to reproduce the paper within physical parameters, the note says so and why, and the
model was not tuned to force agreement. Values are single simulated experiments with seeded noise;
a quick report (fewer geometries, controllers, periods, iterations and sets: see "Resolution")
shows the same figures with more scatter, and its optimizer estimates are not yet converged.
Judge trends and signs on a quick report and absolute numbers on a full one.
"""


def _figure(lines: list[str], figures: Mapping[str, Path], key: str, title: str, caption: str) -> None:
    lines.append(f"### {title}\n")
    if key in figures:
        lines.append(f"![{title}]({figures[key].name})\n")
    else:
        lines.append("*(not drawn: its experiments failed; see Failures)*\n")
    lines.append(caption + "\n")


def _minutes(seconds: float) -> str:
    return f"{int(seconds // 60)} min {seconds % 60:.0f} s"


def write_markdown(path: Path, data: Mapping, table: list[dict], figures: Mapping[str, Path], res,
                   timing: Mapping) -> Path:
    from .plan import FULL, LABELS, MORPHOLOGIES, fig7_cases, fig7_key, sweep_geometries
    from .robustness_report import family_section, family_summary, range_cells

    agree = sum(1 for row in table if row["agrees"])
    judged = sum(1 for row in table if row["agrees"] is not None)
    command = "featherstar paper --quick" if res.name == "quick" else "featherstar paper" if res.name == "full" \
        else f"featherstar.optimizer.paper.paper.generate_report(resolution={res.name!r})"
    when = datetime.datetime.now().strftime("%Y-%m-%d %H:%M")
    lines = [
        f"# The paper's results in simulation ({res.name} resolution)\n",
        "*Control and Morphology Optimization of Passive Asymmetric Structures for Robotic Swimming* "
        "(Obayashi, Vicari et al.), redone with featherstar.\n",
        f"Generated by `{command}` on {when}. **Run time: {_minutes(timing['total_wall_s'])}** on "
        f"{timing['workers']} worker process(es) ({timing['cpu_count']} cores), {timing['tasks']} experiments, "
        f"{timing['simulated_s']:.0f} s of simulated time.\n",
        "## How to read this\n", HOW_TO_READ,
        f"## The paper's numbers beside the simulation ({agree} of {judged} agree)\n",
    ]
    has_family = bool(table) and "robust" in table[0]
    if has_family:
        lines.append(family_summary(table, res) + "\n")
    lines += ["| # | claim | where | paper | simulated | band | agrees | " + ("model family: range (ends) | verdict | "
              if has_family else "") + "note |", "|---|---|---|---|---|---|---|" + ("---|---|" if has_family else "") + "---|"]
    for i, row in enumerate(table, 1):
        lo, hi = row["band"]
        band = "—" if lo == INF else f"> {lo:g}" if hi == INF else f"< {hi:g}" if lo == -INF else f"{lo:g}–{hi:g}"
        verdict = {True: "yes", False: "**no**", None: "n/a"}[row["agrees"]]
        lines.append(f"| {i} | {row['claim']} | {row['source']} | {row['paper']} | {row['simulated_text']} | "
                     f"{band} | {verdict} | " + (range_cells(row) if has_family else "") + f"{row['note']} |")
    lines.append("\n## Figures\n")
    sweep = data["sweep"]["table"]
    counts = {f: len(sweep_geometries(f, res.sweep_geometries)) - 1 for f in ("chordwise", "spanwise")}
    normalized = any(math.isfinite(r["normalized_thrust"]) for r in sweep)
    failed = sum(1 for r in data["sweep"]["runs"] if r["error"])
    _figure(lines, figures, "fig3", "Fig. 3: thrust ratio vs width ratio and length ratio (sweep)",
            f"Per geometry, the maximum over {len(res.sweep_controllers)} controller(s) (t_up/t_down/t_hold s: "
            f"{', '.join(res.describe()['sweep_controllers'])}) of TR (Eq. 3), of the mean thrust"
            + (" and of the caption's normalized thrust T̄_w/T̄_w_spine, T̄_l/T̄_l_root (mean thrust over that of the "
               "bare spine or root part under the same controller). " if normalized else
               ". The caption's normalized thrust T̄_w/T̄_w_spine (T̄_l/T̄_l_root) is undefined here and not drawn: "
               "under every controller run the bare spine (root part), a plain feather, makes ≤ 1 mN of mean "
               "thrust, because the paper's grid has t_up ≤ t_down and a plain plate's TR is t_up/t_down. ")
            + f"{counts['chordwise']} chordwise widths (l = 120 mm) and {counts['spanwise']} spanwise lengths "
            f"(w = 120 mm, l_root = 57.5 mm); {res.sweep_settle_periods} settling + {res.sweep_periods} measured "
            "periods on the kinematic scene, ideal sensor. Pink: the paper's chosen WR 5.5–9.5 and LR 1.5–2.5."
            + (f" {failed} sweep run(s) failed and are left out (their errors are in paper.json)." if failed else ""))
    if sweep:
        lines += ["| family | ratio | max TR | best controller | max T̄ (mN) | max T̄/T̄_ref |", "|---|---|---|---|---|---|"]
        lines += [f"| {r['family']} | {r['ratio']:.2f} | {r['thrust_ratio']:.2f} | {r['best_controller']} | "
                  f"{1e3 * r['mean_thrust_N']:.1f} | {r['normalized_thrust']:.2f} |" for r in sweep]
        lines.append("")
    _figure(lines, figures, "fig5", "Fig. 5: plain, chordwise and spanwise feathers under the symmetric stroke",
            f"Top: thrust over the last two periods with the root angle; middle: integrated thrust; bottom: TR, mean ± "
            f"sd over {res.validation_repeats} sets of {res.validation_periods} periods after {res.settle_periods} "
            "settling (black diamonds: the paper's values). Per-feather runs (featherstar.cosim.swimmer.report): "
            + ", ".join(f"[{f}]({figures[f'fig5_{f}'].name})" for f in MORPHOLOGIES if f"fig5_{f}" in figures) + ".")
    for family in ("chordwise", "spanwise"):
        _figure(lines, figures, f"fig6_{family}", f"Fig. 6: optimization progress, {LABELS[family]} (period 1.5 s)",
                "Observed TR per iteration and the estimated TR (best posterior mean), then the three log10 time "
                "ratios tried (dots) and those of the current best estimate (line).")
    _figure(lines, figures, "fig7", "Fig. 7: optimized strokes for each tested WR and LR, periods 1.5 s and 3 s",
            f"Commanded root angle over one period for the stroke with the best estimated TR (legend); "
            f"{res.iterations} iterations for WR 7.5 / LR 2 at 1.5 s, {res.fig7_iterations} for the others.")
    lines += ["| feather | period (s) | estimated TR | stroke |", "|---|---|---|---|"]
    for family in ("chordwise", "spanwise"):
        for ratio, period in fig7_cases(res, family):
            study = data["studies"].get(fig7_key(family, ratio, period), {})
            lines.append(f"| {family} {'WR' if family == 'chordwise' else 'LR'} {ratio:g} | {period:g} | "
                         f"{study.get('estimated_thrust_ratio', math.nan):.2f} | {_stroke_text(study.get('stroke'))} |")
    lines.append("")
    _figure(lines, figures, "fig8", "Fig. 8: best, baseline and worst controllers, all feathers",
            f"TR and mean thrust, mean ± sd over {res.validation_repeats} validation sets of {res.validation_periods} "
            "periods; best and worst from optimizing for maximum and minimum TR, baseline the symmetric stroke.")
    _figure(lines, figures, "fig9", "Fig. 9: robot displacement and speed, best and worst controllers",
            f"The robot scene run for {res.robot_periods} periods with each feather pair and controller (baseline "
            f"added); mean speed over the periods after the first {res.robot_settle_periods}.")
    if has_family:
        lines += family_section(data, table, res, timing)
    gaps = [row for row in table if row["agrees"] is False]
    lines.append("## Where the model does not reproduce the paper\n")
    lines += [f"- **{row['claim']}** (paper {row['paper']}, simulated {row['simulated_text']}): {row['note']}"
              + (f" Over the model family: {row['robust']} ({row['robust_reason']})." if has_family else "")
              for row in gaps] or ["Every claim agrees at this resolution."]
    lines += ["", "## Resolution\n", f"| setting | this run ({res.name}) | full |", "|---|---|---|"]
    full = FULL.describe()
    lines += [f"| {k} | {v} | {full.get(k)} |" for k, v in res.describe().items() if k != "name"]
    scale = timing["full_planned_simulated_s"] / max(timing["planned_simulated_s"], 1e-9)
    lines += ["", f"This run simulated {timing['planned_simulated_s']:.0f} s of experiments; the full resolution "
              f"simulates {timing['full_planned_simulated_s']:.0f} s ({scale:.0f}× as much), so expect a full "
              f"report to take roughly {scale:.0f}× this run time on this machine"
              + (f" (≈ {scale * timing['total_wall_s'] / 3600:.1f} h)." if scale > 1.5 else ".")
              + f" Regenerate: `{command} --out DIR`; every number is in `paper.json`."]
    failures = data["failures"]
    if failures:
        lines += ["", "## Failures\n"] + [f"- `{label}`: {error}" for label, error in sorted(failures.items())]
    path.write_text("\n".join(lines) + "\n")
    return path
