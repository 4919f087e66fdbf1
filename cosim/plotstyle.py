"""One plotting style for every figure featherstar writes (run, sweep, study, co-design,
calibration, paper, bench and dashboard figures).

Importing the module chooses the headless backend and sets the shared rc parameters (fonts,
sizes, grid, colours), so a figure made after the import has the style. Every figure is then
written through `save_figure`, which finishes it the same way for all writers:

- a discrete axis (periods, iterations, evaluations, repeats) gets integer ticks;
- a bar chart's value axis starts at zero (bars read by their length);
- a legend keeps only entries with a visible handle that stand for something drawn (not a bar
  series of NaNs), and goes away with none left.

`tests/test_figures.py` finds every `save_figure` call site, renders each writer on tiny inputs
and checks what `observe` hands it: labels with units, titles, non-empty panels, legends.
"""
from __future__ import annotations

import re
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterator

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the headless backend)
import numpy as np  # noqa: E402
from matplotlib.container import BarContainer  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

#: The shared look: small, legible fonts, a light grid, the tab10 colours.
RC: dict[str, Any] = {
    "font.size": 9, "axes.titlesize": 9, "axes.labelsize": 9, "figure.titlesize": 10,
    "xtick.labelsize": 8, "ytick.labelsize": 8, "legend.fontsize": 7, "legend.framealpha": 0.8,
    "axes.grid": True, "grid.alpha": 0.3, "grid.linewidth": 0.6,
    "axes.prop_cycle": matplotlib.cycler(color=[f"tab:{c}" for c in (
        "blue", "orange", "green", "red", "purple", "brown", "pink", "gray", "olive", "cyan")]),
    "lines.linewidth": 1.2, "lines.markersize": 4, "savefig.bbox": "tight",
}

#: An axis label naming a count: its ticks are integers (but "period (s)" is a duration).
DISCRETE = re.compile(r"\b(period|iteration|evaluation|trial|repeat|step number|run number)s?\b(?!\s*[\(\[]s[\)\]])",
                      re.IGNORECASE)

_OBSERVERS: list[Callable[[Any, Path], None]] = []


def use_style() -> None:
    """Set the shared rc parameters (done on import; again after a caller's rc changes)."""
    matplotlib.rcParams.update(RC)


use_style()


def _legend_handle_visible(handle: Any) -> bool:
    if not handle.get_visible():
        return False
    if isinstance(handle, Line2D):
        line = handle.get_linestyle() not in ("None", "none", "", " ") and handle.get_linewidth() > 0
        return line or handle.get_marker() not in (None, "None", "none", "", " ")
    if isinstance(handle, Patch):
        face = matplotlib.colors.to_rgba(handle.get_facecolor())[3] * (handle.get_alpha() or 1.0)
        return face > 0 or handle.get_linewidth() > 0
    return True


def _draws_nothing(artist: Any) -> bool:
    """A bar series with no finite bar (all NaN, or none): its legend entry stands for nothing."""
    if not isinstance(artist, BarContainer):
        return False
    heights = np.array([p.get_width() if getattr(artist, "orientation", "") == "horizontal" else p.get_height()
                        for p in artist], float)
    return not np.isfinite(heights).any()


def _clean_legend(ax: Any) -> None:
    legend = ax.get_legend()
    if legend is None:
        return
    handles = list(legend.legend_handles)
    texts = [t.get_text() for t in legend.get_texts()]
    empty = {label for artist, label in zip(*ax.get_legend_handles_labels()) if _draws_nothing(artist)}
    keep = [k for k, h in enumerate(handles)
            if h is not None and _legend_handle_visible(h) and texts[k] not in empty]
    if len(keep) == len(handles):
        return
    drawn, labels = ax.get_legend_handles_labels()
    by_label = dict(zip(labels, drawn))
    pairs = [(by_label[texts[k]], texts[k]) for k in keep if texts[k] in by_label]
    legend.remove()
    if pairs:
        ax.legend([h for h, _ in pairs], [t for _, t in pairs], loc=legend._loc)


def _bars_from_zero(ax: Any) -> None:
    for container in ax.containers:
        if not isinstance(container, BarContainer) or not len(container):
            continue
        horizontal = getattr(container, "orientation", "vertical") == "horizontal"
        if (ax.get_xscale() if horizontal else ax.get_yscale()) != "linear":
            continue
        values = np.array([p.get_width() if horizontal else p.get_height() for p in container], float)
        values = values[np.isfinite(values)]
        if values.size and values.min() >= 0:
            lo, hi = ax.get_xlim() if horizontal else ax.get_ylim()
            if lo > 0:
                (ax.set_xlim if horizontal else ax.set_ylim)(0, hi)


def _integer_ticks(ax: Any) -> None:
    if DISCRETE.search(ax.get_xlabel()) and ax.get_xscale() == "linear":
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    if DISCRETE.search(ax.get_ylabel()) and ax.get_yscale() == "linear":
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))


def finish(fig: Any) -> Any:
    """Apply the style's rules that need the drawn figure (integer ticks, bars from zero, legends)."""
    for ax in fig.axes:
        _integer_ticks(ax)
        _bars_from_zero(ax)
        _clean_legend(ax)
    return fig


def robust_ylim(ax: Any, values: Any, *, inside: Any = None, pad: float = 0.15) -> bool:
    """Scale the y axis to the bulk of `values` (the `inside` samples, e.g. a run's metric window,
    else the 5th to 95th percentile), padded, when the extremes (a start transient) would squash
    it; True when it clipped (say so in the axis label)."""
    y = np.asarray(values, float)
    finite = np.isfinite(y)
    bulk = y[finite & np.asarray(inside, bool)] if inside is not None else y[finite]
    if bulk.size < 2:
        return False
    lo, hi = (float(bulk.min()), float(bulk.max())) if inside is not None else np.percentile(bulk, [5, 95])
    margin = pad * max(hi - lo, 1e-12)
    if np.nanmin(y) >= lo - 3 * margin and np.nanmax(y) <= hi + 3 * margin:
        return False
    ax.set_ylim(lo - margin, hi + margin)
    return True


def save_figure(fig: Any, path: str | Path, *, dpi: int = 110) -> Path:
    """Finish `fig` in the shared style, write it to `path` (PNG) and close it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    finish(fig)
    for observer in list(_OBSERVERS):
        observer(fig, path)
    fig.savefig(path, dpi=dpi, format="png")
    plt.close(fig)
    return path


@contextmanager
def observe() -> Iterator[list[tuple[Any, Path]]]:
    """Collect (figure, path) of every figure `save_figure` writes inside the block."""
    seen: list[tuple[Any, Path]] = []

    def record(fig: Any, path: Path) -> None:
        seen.append((fig, path))

    _OBSERVERS.append(record)
    try:
        yield seen
    finally:
        _OBSERVERS.remove(record)
