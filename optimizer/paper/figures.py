"""The figures of `featherstar paper` (featherstar.optimizer.paper.paper): Figs. 3, 5, 7 and 9 drawn here, Figs. 6 and 8
by featherstar.optimizer.figures, the per-feather Fig. 5 runs by featherstar.cosim.swimmer.report (in the workers).

Each function takes the data `featherstar.optimizer.paper.paper.collect` returns and writes one PNG; missing data (a
failed task) leaves a note in the panel instead of a crash.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the headless backend)
import numpy as np  # noqa: E402

from ...cosim.plotstyle import save_figure  # noqa: E402
from ...cosim.swimmer.stroke import Stroke, root_motion  # noqa: E402
from ..figures import RATIO_LABELS, progress_figure, validation_figure  # noqa: E402
from ..space import symmetric_stroke  # noqa: E402
from ..study import validation_rows  # noqa: E402

DPI = 100
FAMILY_COLOURS = {"plain": "tab:gray", "chordwise": "tab:blue", "spanwise": "tab:orange"}
CONTROLLER_STYLES = {"best": "-", "baseline": ":", "worst": "--"}
PAPER_TR_SYMMETRIC = {"plain": 1.0, "chordwise": 2.0, "spanwise": 2.0}


def _save(fig: plt.Figure, path: Path) -> Path:
    return save_figure(fig, path, dpi=DPI)


def _missing(ax: plt.Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", fontsize=8, transform=ax.transAxes, wrap=True)


def fig3_sweep(table: list[Mapping], path: Path) -> Path:
    """Per geometry, maxima over controllers of TR (Eq. 3), of mean thrust and of the caption's
    normalized thrust, vs WR and LR; the paper's chosen subset shaded, its three ratios dotted."""
    from .plan import FAMILY_RATIOS

    metrics = [("thrust_ratio", "max TR (Eq. 3)", 1.0), ("mean_thrust_N", "max T̄ (mN)", 1e3),
               ("normalized_thrust", r"max $\bar{T}/\bar{T}_\mathrm{ref}$", 1.0)]
    # A metric undefined for every geometry (the normalized thrust, when no reference thrust is
    # positive) gets no panel; the report's caption says why.
    metrics = [m for m in metrics if any(math.isfinite(r[m[0]]) for r in table)] or metrics[:1]
    fig, axes = plt.subplots(len(metrics), 2, figsize=(8, 2.2 * len(metrics) + 0.3), sharex="col", squeeze=False)
    for column, family in enumerate(("chordwise", "spanwise")):
        rows = sorted((r for r in table if r["family"] == family), key=lambda r: r["ratio"])
        chosen = FAMILY_RATIOS[family]
        for row_index, (metric, label, scale) in enumerate(metrics):
            ax = axes[row_index][column]
            ax.axvspan(chosen[0] - 0.25, chosen[-1] + 0.25, color="pink", alpha=0.5, lw=0, label="paper's subset")
            for ratio in chosen:
                ax.axvline(ratio, color="tab:pink", lw=0.8, ls=":")
            values = [scale * r[metric] for r in rows]
            if rows:
                ax.plot([r["ratio"] for r in rows], values, "o-", ms=4, color=FAMILY_COLOURS[family])
            if not any(math.isfinite(v) for v in values):
                _missing(ax, "no data" if not rows else "undefined for every geometry")
            ax.set_ylabel(label, fontsize=8)
            if row_index == 0:
                ax.axhline(1.0, color="k", lw=0.5)
                ax.set_title(f"{family} flaps", fontsize=9)
                ax.legend(fontsize=7, loc="best")
        axes[-1][column].set_xlabel(RATIO_LABELS[family])
    fig.tight_layout()
    return _save(fig, path)


def fig5_symmetric(symmetric: Mapping[str, Mapping], path: Path) -> Path:
    """Raw thrust (last two periods) with the root angle, integrated thrust, TR over the sets."""
    from .plan import LABELS, MORPHOLOGIES, PERIOD_S

    fig = plt.figure(figsize=(9, 7.5))
    grid = fig.add_gridspec(3, 3)
    integrated, bars = fig.add_subplot(grid[1, :]), fig.add_subplot(grid[2, :])
    for column, family in enumerate(MORPHOLOGIES):
        ax = fig.add_subplot(grid[0, column])
        ax.set_title(LABELS[family], fontsize=9)
        run = symmetric.get(family, {})
        if "time_s" not in run:
            _missing(ax, "failed")
            continue
        t, thrust = np.asarray(run["time_s"]), np.asarray(run["thrust_N"])
        last = t >= t[-1] - 2 * PERIOD_S - 0.03
        colour = FAMILY_COLOURS[family]
        ax.plot(t[last], 1e3 * thrust[last], color=colour, lw=0.8)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel("time (s)", fontsize=8)
        twin = ax.twinx()
        twin.plot(t[last], np.degrees(np.asarray(run["angle_rad"])[last]), color="k", lw=0.8, alpha=0.35)
        if column == 0:
            ax.set_ylabel("thrust (mN)")
        if column == len(MORPHOLOGIES) - 1:
            twin.set_ylabel("root angle (°, grey)", fontsize=8)
        impulse = np.concatenate([[0.0], np.cumsum(0.5 * (thrust[1:] + thrust[:-1]) * np.diff(t))])
        integrated.plot(t, 1e3 * impulse, color=colour, label=LABELS[family])
    integrated.axhline(0, color="k", lw=0.5)
    integrated.set_ylabel("∫ thrust dt (mN·s)")
    integrated.set_xlabel("time (s)")
    if integrated.get_legend_handles_labels()[0]:
        integrated.legend(fontsize=7, loc="upper left")
    x = np.arange(len(MORPHOLOGIES))
    values = [symmetric.get(f, {}).get("thrust_ratio", math.nan) for f in MORPHOLOGIES]
    errors = [symmetric.get(f, {}).get("thrust_ratio_sd", 0.0) for f in MORPHOLOGIES]
    bars.bar(x, values, yerr=errors, capsize=3, color=[FAMILY_COLOURS[f] for f in MORPHOLOGIES], label="simulated")
    bars.plot(x, [PAPER_TR_SYMMETRIC[f] for f in MORPHOLOGIES], "kD", ms=6, label="paper (≈)")
    bars.axhline(1.0, color="k", lw=0.5, ls=":")
    bars.set_xticks(x, [LABELS[f] for f in MORPHOLOGIES], fontsize=8)
    bars.set_xlabel("feather")
    bars.set_ylabel("TR (mean ± sd over sets)")
    bars.legend(fontsize=7)
    fig.suptitle(f"Fig. 5: symmetric stroke (ramps 0.25 s, holds 0.5 s, period {PERIOD_S:g} s); "
                 "top: last two periods", fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def _angle_trace(stroke: Stroke, n: int = 300) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, stroke.period_s, n)
    return t, np.degrees([root_motion(stroke, x)[0] for x in t])


def fig7_strokes(studies: Mapping[str, Mapping], res, path: Path) -> Path:
    """Optimized strokes (commanded root angle over one period) per ratio, at each period."""
    from .plan import fig7_cases, fig7_key

    periods = list(res.fig7_periods_s)
    fig, axes = plt.subplots(len(periods), 2, figsize=(8, 2.4 * len(periods)), squeeze=False)
    for column, family in enumerate(("chordwise", "spanwise")):
        cases = fig7_cases(res, family)
        ratios = sorted({r for r, _ in cases})
        shades = plt.get_cmap("Blues" if family == "chordwise" else "Oranges")(np.linspace(0.45, 0.95, len(ratios)))
        for row, period in enumerate(periods):
            ax = axes[row][column]
            t, angle = _angle_trace(symmetric_stroke(period))
            ax.plot(t, angle, color="k", lw=0.8, ls=":", label="symmetric baseline")
            for ratio, shade in zip(ratios, shades):
                study = studies.get(fig7_key(family, ratio, period), {})
                if "stroke" not in study:
                    ax.plot([], [], label=f"{'WR' if family == 'chordwise' else 'LR'} {ratio:g}: failed")
                    continue
                t, angle = _angle_trace(Stroke(**study["stroke"]))
                ax.plot(t, angle, color=shade, lw=1.6,
                        label=f"{'WR' if family == 'chordwise' else 'LR'} {ratio:g} (TR≈{study['estimated_thrust_ratio']:.2f})")
            ax.set_title(f"{family} flaps, period {period:g} s", fontsize=9)
            ax.set_ylabel("root angle (°)", fontsize=8)
            ax.legend(fontsize=6, loc="best")
        axes[-1][column].set_xlabel("time in the period (s)")
    fig.tight_layout()
    return _save(fig, path)


def fig8_rows(studies: Mapping[str, Mapping]) -> list[dict]:
    """Best and baseline from the max study, worst from the min study, per feather."""
    from .plan import LABELS, MORPHOLOGIES

    rows = []
    for family in MORPHOLOGIES:
        best = studies.get(f"{family}-max", {}).get("summary")
        worst = studies.get(f"{family}-min", {}).get("summary")
        if best:
            rows += validation_rows(best, LABELS[family])
        if worst:
            rows += [r for r in validation_rows(worst, LABELS[family]) if r["controller"] == "worst"]
            if not best:
                rows += [r for r in validation_rows(worst, LABELS[family]) if r["controller"] == "baseline"]
    return rows


def fig9_robot(robot: Mapping[str, Mapping], path: Path) -> Path:
    """Body displacement and speed per feather and controller; mean speeds after settling."""
    from .plan import CONTROLLERS, LABELS, MORPHOLOGIES

    fig = plt.figure(figsize=(10, 7))
    grid = fig.add_gridspec(3, 3)
    for column, family in enumerate(MORPHOLOGIES):
        ax_x, ax_v = fig.add_subplot(grid[0, column]), fig.add_subplot(grid[1, column])
        for controller in CONTROLLERS:
            run = robot.get(f"{family}-{controller}", {})
            if "time_s" not in run:
                continue
            style = dict(color=FAMILY_COLOURS[family], ls=CONTROLLER_STYLES[controller], lw=1.2)
            ax_x.plot(run["time_s"], 1e2 * np.asarray(run["position_m"]), label=controller, **style)
            ax_v.plot(run["time_s"], 1e2 * np.asarray(run["speed_m_s"]), **{**style, "lw": 0.7})
        ax_x.set_title(LABELS[family], fontsize=9)
        ax_x.axhline(0, color="k", lw=0.5)
        ax_v.axhline(0, color="k", lw=0.5)
        if ax_x.get_legend_handles_labels()[0]:
            ax_x.legend(fontsize=7)
        ax_v.set_xlabel("time (s)")
        if column == 0:
            ax_x.set_ylabel("displacement (cm)")
            ax_v.set_ylabel("speed (cm/s)")
    ax = fig.add_subplot(grid[2, :])
    width = 0.25
    for k, controller in enumerate(CONTROLLERS):
        values = [1e2 * robot.get(f"{f}-{controller}", {}).get("mean_speed_m_s", math.nan) for f in MORPHOLOGIES]
        ax.bar(np.arange(3) + (k - 1) * width, values, width, label=controller,
               color={"best": "tab:green", "baseline": "tab:gray", "worst": "tab:red"}[controller])
    ax.axhline(2.5, color="k", ls="--", lw=0.8, label="paper: ≈ 2.5 cm/s (chordwise)")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xticks(np.arange(3), [LABELS[f] for f in MORPHOLOGIES], fontsize=8)
    ax.set_xlabel("feather")
    ax.set_ylabel("mean speed (cm/s)")
    ax.legend(fontsize=7, ncol=4)
    fig.suptitle("Fig. 9: robot on its rail with the test bed's best, baseline and worst controllers", fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def compress_png(path: Path) -> None:
    """Line art to a 128-colour palette: a third of the size, no visible change (report in git)."""
    try:
        from PIL import Image
    except ImportError:  # pragma: no cover — pillow comes with matplotlib
        return
    with Image.open(path) as image:
        small = image.convert("RGB").quantize(colors=128, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    small.save(path, optimize=True)


def draw_all(data: Mapping, res, out_dir: Path) -> dict[str, Path]:
    """Every figure of the report, by key; the worker-drawn Fig. 5 runs included where present."""
    figures = {"fig3": fig3_sweep(data["sweep"]["table"], out_dir / "fig3_sweep.png"),
               "fig5": fig5_symmetric(data["symmetric"], out_dir / "fig5_symmetric.png")}
    for family in ("plain", "chordwise", "spanwise"):
        run_png = out_dir / f"fig5_{family}_run.png"
        if run_png.exists() and "time_s" in data["symmetric"].get(family, {}):
            figures[f"fig5_{family}"] = run_png
    for family in ("chordwise", "spanwise"):
        study = data["studies"].get(f"{family}-max", {})
        if "evaluations" in study:
            figures[f"fig6_{family}"] = progress_figure(study["evaluations"], study["estimates"], study["names"],
                                                        out_dir / f"fig6_{family}.png")
    figures["fig7"] = fig7_strokes(data["studies"], res, out_dir / "fig7_strokes.png")
    rows = fig8_rows(data["studies"])
    if rows:
        figures["fig8"] = validation_figure(rows, out_dir / "fig8_validation.png")
    figures["fig9"] = fig9_robot(data["robot"], out_dir / "fig9_robot.png")
    for path in figures.values():
        compress_png(path)
    return figures
