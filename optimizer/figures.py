"""Figures in the style of the paper: Fig. 3 (sweep), Fig. 6 (optimizer progress), Fig. 8 (validation).

Headless (Agg); every function writes one file and returns its path.
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np

from ..cosim.plotstyle import save_figure

_CONTROLLER_ORDER = ("best", "baseline", "worst")
_CONTROLLER_COLOURS = {"best": "tab:green", "baseline": "tab:gray", "worst": "tab:red"}


def progress_figure(
    evaluations: Sequence[Mapping], estimates: Sequence[Mapping | None], names: Sequence[str], path: str | Path,
    *, title: str | None = None,
) -> Path:
    """Fig. 6: observed and estimated TR per iteration, then each variable (observed points and
    the current best-estimate point). `title` names the study (e.g. measured on the bench)."""
    title = title or "Optimizer progress: TR per iteration and the variables tried"
    iterations = np.arange(1, len(evaluations) + 1)
    fig, axes = plt.subplots(1 + len(names), 1, sharex=True, figsize=(6, 1.8 * (1 + len(names))))
    estimated = [math.nan if e is None else e["thrust_ratio"] for e in estimates]
    axes[0].plot(iterations, [e["thrust_ratio"] for e in evaluations], "o", ms=4, label="observed")
    axes[0].plot(iterations, estimated, "-", lw=2, label="estimated (best posterior mean)")
    axes[0].set_ylabel("TR")
    axes[0].legend(fontsize=7)
    for ax, name in zip(axes[1:], names):
        ax.plot(iterations, [e["params"][name] for e in evaluations], "o", ms=4, color="tab:blue")
        ax.plot(iterations, [math.nan if e is None else e["params"][name] for e in estimates], "-", color="tab:orange")
        ax.set_ylabel(label(name))
    axes[-1].set_xlabel("iteration")
    axes[0].set_title(title)
    fig.tight_layout()
    return _save(fig, path)


def validation_figure(rows: Sequence[Mapping], path: str | Path, *, title: str | None = None) -> Path:
    """Fig. 8: TR and mean thrust (mean ± sd over the validation repeats) per morphology and
    controller. Rows: morphology, controller (best/baseline/worst), thrust_ratio(_sd), mean_thrust_N(_sd)."""
    title = title or "Validation: best, baseline and worst controllers (mean ± sd over repeats)"
    morphologies = list(dict.fromkeys(r["morphology"] for r in rows))
    controllers = [c for c in _CONTROLLER_ORDER if any(r["controller"] == c for r in rows)]
    width = 0.8 / max(len(controllers), 1)
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(6, 5))
    for k, controller in enumerate(controllers):
        for ax, key, scale in ((axes[0], "thrust_ratio", 1.0), (axes[1], "mean_thrust_N", 1e3)):
            values, errors = [], []
            for morphology in morphologies:
                row = next((r for r in rows if r["morphology"] == morphology and r["controller"] == controller), None)
                values.append(math.nan if row is None else row[key] * scale)
                errors.append(0.0 if row is None else _sd(row, key) * scale)
            x = np.arange(len(morphologies)) + (k - (len(controllers) - 1) / 2) * width
            ax.bar(x, values, width, yerr=errors, capsize=3, label=controller, color=_CONTROLLER_COLOURS[controller])
    axes[0].axhline(1.0, color="k", lw=0.8, ls=":")
    axes[0].set_ylabel("TR")
    axes[0].legend(fontsize=7)
    axes[1].set_ylabel("mean thrust (mN)")
    axes[1].set_xticks(np.arange(len(morphologies)), morphologies, fontsize=8)
    axes[1].set_xlabel("feather")
    axes[0].set_title(title)
    fig.tight_layout()
    return _save(fig, path)


def _finite(value: object) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


def sweep_figure(table: Sequence[Mapping], metrics: Sequence[str], path: str | Path, *, note: str | None = None) -> Path:
    """Fig. 3: per-geometry maxima over controllers against WR or LR, one panel per family and
    metric. A metric undefined for every geometry gets no panel: the figure says so under its
    title, with `note` (the sweep's reason) when given."""
    families = list(dict.fromkeys(r["family"] for r in table))
    drawn = [m for m in metrics if any(_finite(r[m]) for r in table)] or list(metrics[:1])
    left_out = [m for m in metrics if m not in drawn]
    fig, axes = plt.subplots(len(drawn), len(families), figsize=(4 * len(families), 2.6 * len(drawn) + 0.6),
                             squeeze=False)
    for column, family in enumerate(families):
        rows = sorted((r for r in table if r["family"] == family), key=lambda r: r["ratio"])
        for row_index, metric in enumerate(drawn):
            ax = axes[row_index][column]
            ax.plot([r["ratio"] for r in rows], [r[metric] for r in rows], "o-", ms=3)
            ax.set_ylabel(f"max {label(metric)}")
            ax.set_xlabel(RATIO_LABELS.get(family, "ratio"))
            ax.set_title(f"{family} flaps")
    title = "Sweep: per geometry, the maximum over the controllers"
    if left_out:
        why = "not drawn: " + ", ".join(label(m) for m in left_out) + " (undefined for every geometry"
        title += "\n" + textwrap.fill(why + (f": {note})" if note else ")"), 45 * len(families))
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


#: The sweep's abscissa per family (mathtext subscripts, not code names).
RATIO_LABELS = {"chordwise": r"WR = $w/w_\mathrm{spine}$", "spanwise": r"LR = $l/l_\mathrm{root}$"}


#: Axis labels for the names the optimizer's tables use (a figure speaks to a reader, not to code).
LABELS = {
    "thrust_ratio": "TR", "mean_thrust_N": "mean thrust (N)", "mean_thrust_mN": "mean thrust (mN)",
    "normalized_thrust": r"normalized thrust $\bar{T}/\bar{T}_\mathrm{ref}$", "mean_speed_m_s": "mean speed (m/s)",
    "t_up_s": r"$t_\mathrm{up}$ (s)", "t_hold_up_s": r"$t_\mathrm{hold,up}$ (s)", "t_down_s": r"$t_\mathrm{down}$ (s)",
    "t_hold_down_s": r"$t_\mathrm{hold,down}$ (s)",
    "period_s": "period (s)", "amplitude_deg": "amplitude, peak to peak (°)",
    "log10_up_down": r"$\log_{10}(t_\mathrm{up}/t_\mathrm{down})$",
    "log10_hold_up_down": r"$\log_{10}(t_\mathrm{hold,up}/t_\mathrm{hold,down})$",
    "log10_hold_move": r"$\log_{10}$(holds/moves)",
}


def label(name: str) -> str:
    """A reader's label for a table column or search variable (units from the name's suffix)."""
    if name in LABELS:
        return LABELS[name]
    for suffix, unit in (("_s", "s"), ("_deg", "°"), ("_rad", "rad"), ("_N", "N"), ("_m", "m")):
        if name.endswith(suffix):
            return f"{name[: -len(suffix)].replace('_', ' ')} ({unit})"
    return name.replace("_", " ")


def _sd(row: Mapping, key: str) -> float:
    sd = row.get(key.replace("_N", "") + "_sd_N" if key.endswith("_N") else key + "_sd", 0.0)
    return 0.0 if sd is None or not math.isfinite(sd) else float(sd)


def _save(fig: plt.Figure, path: str | Path) -> Path:
    return save_figure(fig, path, dpi=120)
