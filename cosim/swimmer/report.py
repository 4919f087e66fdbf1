"""What `featherstar run` writes: a summary table, summary.json, results.csv and a figure like the
paper's Fig. 5 (thrust with the root angle, integrated thrust, thrust ratio per period)."""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from .run_figure import run_figure
from ..plotstyle import save_figure
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
    """The console summary; an incomplete run says so on its first line, before any number."""
    lines = [f"scene: {summary.get('scene', '?')}"]
    if summary.get("incomplete_reason"):
        lines.insert(0, f"INCOMPLETE (not a result): {summary['incomplete_reason']}")
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
    """The run's figure (featherstar.cosim.swimmer.run_figure) as a PNG at `path`."""
    save_figure(run_figure(result), path)
