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
             f"wall and CPU time as ratios to featherstar strong's in the same run (best of {settings['repeats']}).", ""]
    for name, system in result["systems"].items():
        window = system["metric_window_s"]
        lines += [f"**{name}**: {system['description']}, {system['periods']} periods, TR and mean thrust over "
                  f"{window[0]:g}-{window[1]:g} s", "",
                  "| run | coupling | TR error | mean thrust error | max \\|ΔT\\| / peak, first period | wall time | CPU time |",
                  "|---|---|---|---|---|---|---|"]
        for row in system["rows"]:
            if row["status"] != "ok":
                lines.append(f"| {row['run']} | {row['coupling']} | {row['status']}: {row['reason']} | | | | |")
                continue
            ratio, cpu_ratio = row.get("wall_over_featherstar_strong"), row.get("cpu_over_featherstar_strong")
            wall = f"{ratio:.2f}x" if ratio is not None else f"{row['wall_s']:.2f} s"
            cpu = f"{cpu_ratio:.2f}x" if cpu_ratio is not None else f"{row['cpu_s']:.2f} s"
            lines.append(f"| {row['run']} | {row['coupling']} | {_sci(row['tr_rel_error'])} | "
                         f"{_sci(row['mean_thrust_rel_error'])} | {_sci(row['first_period_thrust_error_rel_peak'])} | "
                         f"{wall} | {cpu} |")
        same = system.get("identical_records") or []
        if same:
            lines += ["", "Bit-identical thrust records: " + "; ".join(" = ".join(g) for g in same) + "."]
        lines.append("")
    lines += compat_table(result.get("fmu_compatibility"))
    return "\n".join(lines).rstrip() + "\n"


def _cell(entry: dict[str, Any]) -> str:
    if entry["status"] != "ok":
        return f"{entry['status']}: {entry['reason']}"
    if "bit_identical_to_fmpy" not in entry:
        return "runs"
    if entry["bit_identical_to_fmpy"]:
        return "runs, bit-identical"
    return f"runs, max diff {entry['max_abs_diff_to_fmpy']:.0e}"


def compat_table(matrix: dict[str, Any] | str | None) -> list[str]:
    """Every catalog FMU in every master: runs or not, and how far from fmpy's numbers."""
    if not isinstance(matrix, dict):
        return [f"FMU compatibility: {matrix}"] if matrix else []
    masters = ("fmpy", "libcosim", "ecos")
    lines = ["**Every catalog FMU alone in each master** (one input held at 0.2 for 0.1 s at a 1 ms step; "
             "differences to fmpy's record of the same output)", "",
             "| FMU | FMI | fmpy | libcosim | Ecos |", "|---|---|---|---|---|"]
    for model, versions in matrix.items():
        for version, entry in versions.items():
            cells = [("runs" if entry[m]["status"] == "ok" else _cell(entry[m])) if m == "fmpy" else _cell(entry[m])
                     for m in masters]
            lines.append(f"| {model} | {version[3:]}.0 | " + " | ".join(cells) + " |")
    return lines + [""]


ERRORS = (("tr_rel_error", "TR relative error"),
          ("first_period_thrust_error_rel_peak", "max |dT| / peak thrust, first period"))


def plot(result: dict[str, Any], path: Path) -> None:
    """Error against wall time, log-log: TR error (top) and the first period's pointwise thrust
    error (bottom), one column per system; a zero error is drawn at the panel's floor and named so."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from featherstar.cosim.plotstyle import save_figure

    systems = result["systems"]
    fig, axes = plt.subplots(2, len(systems), figsize=(6.5 * len(systems), 8), squeeze=False)
    for col, (name, system) in enumerate(systems.items()):
        rows = [r for r in system["rows"] if r["status"] == "ok"]
        for ax, (key, text) in zip(axes[:, col], ERRORS):
            floor = min([r[key] for r in rows if r[key] > 0] or [1e-12]) / 10
            for row in rows:
                marker = next((m for prefix, m in MARKERS.items() if row["run"].startswith(prefix)), "x")
                ax.loglog(row["wall_s"], max(row[key], floor), marker=marker, linestyle="none", markersize=8,
                          alpha=0.8, label=row["run"] + (" (error 0)" if row[key] == 0 else ""))
            ax.set_xlabel(f"wall time (s, best of {result['settings']['repeats']})")
            ax.set_ylabel(f"{text}\nagainst strong at rtol {result['settings']['reference_rtol']:g}")
            ax.set_title(f"{name}: {system['description']}", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
