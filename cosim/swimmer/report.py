"""What `featherstar run` writes: a summary table, summary.json, results.csv and a figure like the
paper's Fig. 5 (thrust with the root angle, integrated thrust, thrust ratio per period)."""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..jsonable import json_safe

SUMMARY_ROWS = (
    ("thrust_ratio", "thrust ratio TR (Eq. 3)", "{:.4f}", 1.0, ""),
    ("mean_thrust_N", "mean thrust (Eq. 2)", "{:.3f}", 1e3, "mN"),
    ("mean_speed_m_s", "robot mean speed", "{:.2f}", 1e2, "cm/s"),
    ("periods_used", "whole periods in the window", "{}", 1, ""),
    ("coupling", "coupling", "{}", None, ""),
    ("wall_time_s", "wall time", "{:.2f}", 1.0, "s"),
)


def summary_table(summary: dict[str, Any]) -> str:
    lines = [f"scene: {summary.get('scene', '?')}"]
    for key, label, fmt, scale, unit in SUMMARY_ROWS:
        if key not in summary:
            continue
        value = summary[key]
        if scale not in (None, 1) and isinstance(value, (int, float)):
            value = value * scale
        text = fmt.format(value) if value is not None else "-"
        lines.append(f"  {label:<30} {text} {unit}".rstrip())
    if "window_s" in summary:
        a, b = summary["window_s"]
        lines.append(f"  {'metric window':<30} {a:.3g}–{b:.3g} s")
    per = summary.get("per_period_thrust_ratio")
    if per:
        lines.append(f"  {'TR per period':<30} " + ", ".join(f"{v:.3f}" for v in per))
    lines += _realtime_lines(summary)
    if "terminated_by" in summary:
        lines.append(f"  {'ended by':<30} {summary['terminated_by']} (asked to terminate) at "
                     f"t={summary['terminated_at_s']:.6g} s of {summary.get('t_end_s', 0.0):.6g} s")
    if "error" in summary:
        lines.append(f"  FAILED: {summary['error']}")
    return "\n".join(lines)


def _realtime_lines(summary: dict[str, Any]) -> list[str]:
    """What a hardware run must not hide: misses, gaps, reconnects, excluded periods, the
    safe position, and why a run is not complete."""
    lines = []
    if summary.get("deadline_misses"):
        lines.append(f"  {'deadline misses':<30} {summary['deadline_misses']} "
                     f"(worst {1e3 * summary.get('worst_lateness_s', 0.0):.1f} ms late)")
    for key, label in (("gaps", "data gaps (device recovered)"), ("reconnects", "reconnects"),
                       ("lags", "device behind real time")):
        if summary.get(key):
            lines.append(f"  {label:<30} {summary[key]}")
    validity = summary.get("validity") or {}
    for bad in validity.get("invalid_periods", []):
        lines.append(f"  {'excluded period ' + str(bad['period']):<30} "
                     + "; ".join(bad["reasons"][:3]))
    if validity.get("invalid_periods"):
        lines.append(f"  {'valid periods':<30} {validity['valid_periods']} "
                     f"(TR and mean thrust use these only)")
    for name, ok in (summary.get("safe_position_confirmed") or {}).items():
        if not ok:
            lines.append(f"  WARNING: {name} did not acknowledge its safe position")
    for warning in summary.get("warnings", []):
        lines.append(f"  WARNING: {warning}")
    if "incomplete_reason" in summary:
        lines.append(f"  INCOMPLETE: {summary['incomplete_reason']}")
    return lines


#: What a run writes into its --out folder (and clears there before it starts).
OUTPUT_FILES = ("summary.json", "results.csv", "thrust.png")


def clear_outputs(out_dir: str | Path) -> list[Path]:
    """Remove an earlier run's outputs from `out_dir`, so that a run refused or failed later
    cannot leave a stale `complete: true` beside it; returns the files removed."""
    removed = []
    for name in OUTPUT_FILES:
        path = Path(out_dir) / name
        if path.is_file() or path.is_symlink():
            path.unlink()
            removed.append(path)
    return removed


def _write_atomically(path: Path, write: Any) -> None:
    """write(tmp_path), then rename over `path`: a reader never sees half a file."""
    tmp = path.with_name(f".{path.name}.partial")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _summary_payload(result: Any) -> str:
    payload = dict(result.summary)
    payload["complete"] = result.complete
    payload["info"] = result.info
    payload["scene_definition"] = result.scene.to_dict()
    return json.dumps(json_safe(payload), indent=2, allow_nan=False) + "\n"


def write_outputs(result: Any, out_dir: str | Path, *, figure: bool = True) -> dict[str, Path]:
    """results.csv, then summary.json, then the figure. The figure is optional post-processing:
    when it fails the results stay written, and the failure becomes a warning in the summary
    (`summary["warnings"]`) that summary.json is rewritten with."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    clear_outputs(out)
    paths = {"summary": out / "summary.json", "results": out / "results.csv"}
    _write_atomically(paths["results"], lambda tmp: _write_results(result, tmp))
    _write_atomically(paths["summary"], lambda tmp: tmp.write_text(_summary_payload(result)))
    if figure and len(result.time) > 1:
        target = out / "thrust.png"
        try:
            _write_atomically(target, lambda tmp: plot_run(result, tmp))
        except Exception as exc:   # a figure is never worth the run: keep the results, say why
            result.summary.setdefault("warnings", []).append(
                f"figure not written: {type(exc).__name__}: {exc}")
            _write_atomically(paths["summary"], lambda tmp: tmp.write_text(_summary_payload(result)))
        else:
            paths["figure"] = target
    return paths


def _write_results(result: Any, path: Path) -> None:
    names = list(result.signals)
    header = ",".join(["time [s]"] + [f"{n} [{result.units.get(n, '')}]" for n in names])
    columns = [result.time] + [result.signals[n] for n in names]
    if all(c.dtype == np.float64 for c in columns):
        data = np.column_stack(columns) if len(result.time) else np.zeros((0, 1 + len(names)))
        np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.10g")
    else:  # FMU ports of other types: integers in full, Booleans 0/1, strings quoted, bytes in hex
        import csv

        with path.open("w", newline="") as fh:
            fh.write(header + "\n")
            writer = csv.writer(fh)
            for row in zip(*columns):
                writer.writerow([_cell(v) for v in row])


def _cell(value: Any) -> str:
    if isinstance(value, (bytes, bytearray)):
        return bytes(value).hex()
    if isinstance(value, (bool, np.bool_)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.10g}"
    return "" if value is None else str(value)


def plot_run(result: Any, path: str | Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sc = result.scene
    t = result.time
    thrust_name, angle_name = sc.metrics.thrust, sc.metrics.angle
    has_speed = bool(sc.metrics.position or sc.metrics.speed)
    n_rows = 3 + (1 if has_speed else 0)
    fig, axes = plt.subplots(n_rows, 1, figsize=(8, 2.4 * n_rows), constrained_layout=True)
    try:
        s = result.summary
        title = f"{sc.name}: TR = {s.get('thrust_ratio', float('nan')):.3f}, mean thrust = " \
                f"{1e3 * s.get('mean_thrust_N', float('nan')):.2f} mN"
        if "mean_speed_m_s" in s:
            title += f", mean speed = {1e2 * s['mean_speed_m_s']:.2f} cm/s"
        fig.suptitle(title)
        ax = axes[0]
        if thrust_name in result.signals:
            thrust = result.signals[thrust_name]
            ax.plot(t, 1e3 * thrust, color="C0", lw=0.8, label="thrust")
            ax.axhline(0, color="k", lw=0.5)
            ax.set_ylabel("thrust (mN)")
            if angle_name in result.signals:
                ax2 = ax.twinx()
                ax2.plot(t, np.degrees(result.signals[angle_name]), color="C3", lw=0.8, alpha=0.7)
                ax2.set_ylabel("root angle (°)", color="C3")
            if "window_s" in s:
                ax.axvspan(*s["window_s"], color="0.9", zorder=-1)
            dt = np.diff(t)
            integ = np.concatenate([[0.0], np.cumsum(0.5 * (thrust[1:] + thrust[:-1]) * dt)])
            axes[1].plot(t, 1e3 * integ, color="C0")
            axes[1].set_ylabel("∫ thrust dt (mN·s)")
            axes[1].axhline(0, color="k", lw=0.5)
            per = s.get("per_period_thrust_ratio") or []
            if per:
                axes[2].bar(np.arange(1, len(per) + 1), per, color="C0")
                axes[2].axhline(s.get("thrust_ratio", np.nan), color="C1", label="window TR")
                axes[2].axhline(1.0, color="k", lw=0.5)
                axes[2].set_xlabel("period in the metric window")
                axes[2].legend(loc="lower right")
            axes[2].set_ylabel("TR")
        axes[1].set_xlabel("time (s)")
        axes[0].set_xlabel("time (s)")
        if has_speed:
            ax = axes[3]
            if sc.metrics.position in result.signals:
                ax.plot(t, 1e2 * result.signals[sc.metrics.position], color="C2")
                ax.set_ylabel("body position (cm)")
            if sc.metrics.speed in result.signals:
                ax2 = ax.twinx()
                ax2.plot(t, 1e2 * result.signals[sc.metrics.speed], color="C4", lw=0.6)
                ax2.set_ylabel("speed (cm/s)", color="C4")
            ax.set_xlabel("time (s)")
        fig.savefig(path, dpi=110, format="png")
    finally:
        plt.close(fig)
