"""The figure of one run, like the paper's Fig. 5: thrust with the root angle, integrated thrust,
TR per period (and the body's motion for the robot).

A figure carries its run's validity, so it cannot look valid when the run was not: an
incomplete run says INCOMPLETE and why at the head of the title; the metric window and the
periods a hardware run excluded are shaded and named in the legend; the per-period panel marks
excluded periods and says so when no period is valid. The title names the scene and the
feather's morphology. The thrust axis is scaled to the metric window, so a start transient does
not squash it (the transient is clipped, and the axis says so).
"""
from __future__ import annotations

from typing import Any

import numpy as np


def _morphology(scene: Any) -> str:
    """The morphology of the scene's feathers ("chordwise", "plain and spanwise"), or ""."""
    found = []
    for block in scene.blocks:
        options = block.settings.get("options", {}) if hasattr(block.settings, "get") else {}
        value = block.overrides.get("morphology", options.get("morphology") if hasattr(options, "get") else None)
        if value and str(value) not in found:
            found.append(str(value))
    return " and ".join(found)


def _title(result: Any) -> str:
    s = result.summary
    morphology = _morphology(result.scene)
    head = f"{result.scene.name}" + (f" ({morphology} feather)" if morphology else "")
    numbers = (f"TR = {s.get('thrust_ratio', float('nan')):.3f}, mean thrust = "
               f"{1e3 * s.get('mean_thrust_N', float('nan')):.2f} mN")
    if "mean_speed_m_s" in s:
        numbers += f", mean speed = {1e2 * s['mean_speed_m_s']:.2f} cm/s"
    if not result.complete:
        reason = str(s.get("incomplete_reason") or s.get("error") or "see summary.json")
        return f"INCOMPLETE: {reason[:90]}\n{head}: {numbers} (not a result)"
    return f"{head}: {numbers}"


def _excluded(summary: dict[str, Any]) -> list[tuple[int, float, float, str]]:
    """(period number, start s, end s, reasons) of each period a hardware run excluded."""
    period = summary.get("period_s")
    out = []
    for p in (summary.get("validity") or {}).get("invalid_periods", []):
        if period and "start_s" in p:
            out.append((int(p["period"]), float(p["start_s"]), float(p["start_s"]) + float(period),
                        ", ".join(p.get("reasons", []))))
    return out


def run_figure(result: Any) -> Any:
    """The run's figure (a matplotlib Figure; the caller saves and closes it)."""
    from ..plotstyle import robust_ylim   # first: it chooses the headless backend
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    sc, s, t = result.scene, result.summary, result.time
    thrust_name, angle_name = sc.metrics.thrust, sc.metrics.angle
    has_speed = bool(sc.metrics.position or sc.metrics.speed)
    n_rows = 3 + (1 if has_speed else 0)
    fig, axes = plt.subplots(n_rows, 1, figsize=(8, 2.5 * n_rows), constrained_layout=True)
    fig.suptitle(_title(result), color="C3" if not result.complete else "black")
    excluded = _excluded(s)
    ax = axes[0]
    if thrust_name in result.signals:
        thrust = result.signals[thrust_name]
        ax.plot(t, 1e3 * thrust, color="C0", lw=0.8, label=f"thrust ({thrust_name})")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel("thrust (mN)")
        if "window_s" in s:
            a, b = s["window_s"]
            ax.axvspan(a, b, color="0.9", zorder=-1, label="metric window")
            if robust_ylim(ax, 1e3 * thrust, inside=(t >= a) & (t <= b)):
                ax.set_ylabel("thrust (mN)\n(start transient clipped)")
        for k, (number, start, end, reasons) in enumerate(excluded):
            ax.axvspan(start, end, color="C3", alpha=0.2, zorder=-1,
                       label="excluded period" if k == 0 else None)
            ax.text(0.5 * (start + end), 0.98, f"{number}", transform=ax.get_xaxis_transform(),
                    ha="center", va="top", fontsize=7, color="C3")
        if angle_name in result.signals:
            ax2 = ax.twinx()
            ax2.plot(t, np.degrees(result.signals[angle_name]), color="C3", lw=0.8, alpha=0.7)
            ax2.set_ylabel("root angle (°)", color="C3")
        ax.legend(loc="upper left", fontsize=7)
        dt = np.diff(t)
        integ = np.concatenate([[0.0], np.cumsum(0.5 * (thrust[1:] + thrust[:-1]) * dt)])
        axes[1].plot(t, 1e3 * integ, color="C0")
        axes[1].set_ylabel("∫ thrust dt (mN·s)")
        axes[1].axhline(0, color="k", lw=0.5)
    else:
        ax.text(0.5, 0.5, f"no thrust signal recorded ({thrust_name or 'metrics.thrust unset'})",
                ha="center", va="center", transform=ax.transAxes)
    per = s.get("per_period_thrust_ratio") or []
    bars = axes[2]
    if per:
        numbers = np.arange(1, len(per) + 1)
        gone = {number for number, *_ in excluded}
        kept = [k for k, n in enumerate(numbers) if n not in gone]
        dropped = [k for k, n in enumerate(numbers) if n in gone]
        bars.bar(numbers[kept], np.asarray(per, float)[kept], color="C0", label="TR of the period")
        if dropped:
            bars.bar(numbers[dropped], np.asarray(per, float)[dropped], color="0.75", label="excluded period")
        bars.axhline(s.get("thrust_ratio", np.nan), color="C1", label="window TR")
        bars.axhline(1.0, color="k", lw=0.5)
        bars.legend(loc="lower right", fontsize=7)
        bars.xaxis.set_major_locator(MaxNLocator(integer=True))
        finite = np.asarray(per, float)[np.isfinite(np.asarray(per, float))]
        bars.set_ylim(0, max(1.2, 1.1 * float(finite.max())) if finite.size else 1.2)
    else:
        reason = (s.get("validity") or {}).get("reason") or "no whole period in the metric window"
        bars.text(0.5, 0.5, f"no period to show: {reason}", ha="center", va="center", transform=bars.transAxes)
    bars.set_xlabel("period in the metric window")
    bars.set_ylabel("TR")
    axes[0].set_xlabel("time (s)")
    axes[1].set_xlabel("time (s)")
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
    plt.close(fig)   # the caller saves it; pyplot keeps no reference
    return fig
