"""The peers benchmark's outputs from its JSON: the README's comparison table (markdown) and the
error-against-wall-time plot. Nothing here measures; every number comes from the result dict."""
from __future__ import annotations

from pathlib import Path
from typing import Any

MARKERS = {"featherstar": "o", "libcosim": "s", "Ecos": "D", "fmpy": "^"}


def _sci(value: float) -> str:
    return "0" if value == 0 else f"{value:.1e}"


def markdown_table(result: dict[str, Any]) -> str:
    """One table per system: the errors against the tight reference and the wall-time ratio."""
    settings = result["settings"]
    lines = [f"Thrust against featherstar strong at rtol {settings['reference_rtol']:g} (relative errors); "
             f"co-simulation at a {1e3 * settings['step_s']:g} ms step, every FMU at rtol {settings['rtol']:g}; "
             f"wall time as a ratio to featherstar strong in the same run (best of {settings['repeats']}).", ""]
    for name, system in result["systems"].items():
        window = system["metric_window_s"]
        lines += [f"**{name}**: {system['description']}, {system['periods']} periods, TR and mean thrust over "
                  f"{window[0]:g}-{window[1]:g} s", "",
                  "| run | coupling | TR error | mean thrust error | max \\|ΔT\\| / peak, first period | wall time |",
                  "|---|---|---|---|---|---|"]
        for row in system["rows"]:
            if row["status"] != "ok":
                lines.append(f"| {row['run']} | {row['coupling']} | {row['status']}: {row['reason']} | | | |")
                continue
            ratio = row.get("wall_over_featherstar_strong")
            wall = f"{ratio:.2f}x" if ratio is not None else f"{row['wall_s']:.2f} s"
            lines.append(f"| {row['run']} | {row['coupling']} | {_sci(row['tr_rel_error'])} | "
                         f"{_sci(row['mean_thrust_rel_error'])} | {_sci(row['first_period_thrust_error_rel_peak'])} | "
                         f"{wall} |")
        same = system.get("identical_records") or []
        if same:
            lines += ["", "Bit-identical thrust records: " + "; ".join(" = ".join(g) for g in same) + "."]
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def plot(result: dict[str, Any], path: Path) -> None:
    """TR relative error against wall time, log-log, one panel per system (zero errors drawn at
    the bottom edge and labelled so)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    systems = result["systems"]
    fig, axes = plt.subplots(1, len(systems), figsize=(6.5 * len(systems), 4.5), squeeze=False)
    for ax, (name, system) in zip(axes[0], systems.items()):
        rows = [r for r in system["rows"] if r["status"] == "ok"]
        floor = min([r["tr_rel_error"] for r in rows if r["tr_rel_error"] > 0] or [1e-12]) / 10
        for row in rows:
            marker = next((m for key, m in MARKERS.items() if row["run"].startswith(key)), "x")
            error = max(row["tr_rel_error"], floor)
            ax.loglog(row["wall_s"], error, marker=marker, linestyle="none", markersize=8, label=row["run"])
            ax.annotate(row["run"] + (" (0)" if row["tr_rel_error"] == 0 else ""), (row["wall_s"], error),
                        fontsize=7, xytext=(4, 3), textcoords="offset points")
        ax.set_xlabel("wall time, s (best of %d)" % result["settings"]["repeats"])
        ax.set_ylabel("TR relative error against strong at rtol %g" % result["settings"]["reference_rtol"])
        ax.set_title(f"{name}: {system['description']}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
