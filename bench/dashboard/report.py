"""The dashboard report: headline ratios, plots and the markdown page."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ..cosim.scene.guards import LOOP_STEP_PER_TIME_CONSTANT, SAMPLES_PER_RAMP
from .timing import METHODS, REFERENCES


def load_json(out: Path, name: str) -> dict[str, Any] | None:
    path = out / name
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def derive(data: dict[str, Any], quick: bool) -> dict[str, Any]:
    """The headline numbers, each a ratio measured side by side within one benchmark run."""
    s: dict[str, Any] = {}
    m = data.get("dashboard_measurements")
    if m:
        cg = m["cost_growth"]
        s["ratios_by_n"] = {row["n_units"]: {k: v for k, v in row.items() if "/" in k} for row in cg["by_n"]}
        s["ratios_by_duration"] = {row["t_end_s"]: {k: v for k, v in row.items() if "/" in k}
                                   for row in cg["by_duration"]}
        s["cost_per_simulated_s"] = {
            method: {row["n_units"]: row[method]["wall_s"] / row["t_end_s"] for row in cg["by_n"]}
            for method in METHODS}
        for method in METHODS:  # growth exponent: wall ∝ N^a
            xs = [(row["n_units"], row[method]["wall_s"]) for row in cg["by_n"] if row[method]["wall_s"] > 0]
            if len(xs) >= 2:
                (n0, w0), (n1, w1) = xs[0], xs[-1]
                s.setdefault("n_growth_exponent", {})[method] = math.log(w1 / w0) / math.log(n1 / n0)
            ds = [(row["t_end_s"], row[method]["wall_s"]) for row in cg["by_duration"]]
            if len(ds) >= 2:
                (d0, w0), (d1, w1) = ds[0], ds[-1]
                s.setdefault("duration_growth_exponent", {})[method] = math.log(w1 / w0) / math.log(d1 / d0)
    fmu = data.get("fmu_models") or {}
    if m:
        over = {}
        for name, ref in m["rhs_call_cost"].items():
            row = dict(ref)  # measured side by side by the dashboard
            cost = fmu.get("step_cost", {}).get(name, {})
            if cost:  # bench/fmu_models.py, its own process: the CS step and the bare call overhead
                row["fmu_cs_do_step_1ms_us"] = cost.get("cs_stroke", cost.get("cs_rest", {})).get("do_step_us")
                row["fmu_python_call_overhead_us"] = cost.get("me", {}).get("python_call_overhead_us")
            over[name] = row
        s["fmu_call_overhead"] = over
    if fmu:
        s["fmu_vs_casadi_stroke_run"] = {name: {k: v.get("wall_ratio_to_casadi") for k, v in run.items()
                                                if isinstance(v, dict) and "wall_ratio_to_casadi" in v}
                                         for name, run in fmu.get("stroke_runs", {}).items()}
    wp = data.get("cosim_work_precision")
    if wp:
        s["cosim_goal"] = {e["scene"]: e.get("goal") for e in wp.get("scenes", [])}
    opt = data.get("optimizer_timing") or {}
    syn = data.get("optimizer_timing_synthetic") or {}
    if opt and not quick:
        s["optimizer"] = {"source": "bench/optimizer_timing.py (FMU master)",
                          "optimization_wall_s": opt["optimization"]["wall_s"],
                          "iterations": opt["optimization"]["iterations"],
                          "simulation_share": opt["optimization"]["simulation_share"],
                          "sweep_wall_s": opt["sweep"]["wall_s"], "sweep_runs": opt["sweep"]["runs"],
                          "sweep_workers": opt["sweep"]["workers"]}
    elif syn and m and "optimizer_evaluation" in m:
        ev = m["optimizer_evaluation"]
        per_iter = syn["optimization"]["optimizer_s"] / syn["optimization"]["iterations"]
        workers = syn["sweep"].get("workers") or 1
        s["optimizer"] = {
            "source": "estimate (--quick): optimizer overhead from bench/optimizer_timing.py --synthetic, "
                      "simulation cost from one real evaluation measured by the dashboard",
            "optimizer_overhead_per_iteration_s": per_iter,
            "evaluation_wall_s": ev["evaluation_wall_s"],
            "estimated_30_iterations_wall_s": 30 * (ev["evaluation_wall_s"] + per_iter),
            "estimated_simulation_share": ev["evaluation_wall_s"] / (ev["evaluation_wall_s"] + per_iter),
            "sweep_run_wall_s": ev["sweep_run_wall_s"],
            "estimated_full_sweep_wall_s": 444 * ev["sweep_run_wall_s"] / workers,
            "sweep_workers": workers,
            "goals_s": {"30_iterations": 60.0, "full_sweep": 120.0},
        }
        if opt and not opt.get("quick", True):
            s["optimizer"]["last_full_run"] = {"optimization_wall_s": opt["optimization"]["wall_s"],
                                               "sweep_wall_s": opt["sweep"]["wall_s"]}
    hil = data.get("hil_loop_rate")
    if hil:
        s["hil"] = {f"{r['rate_hz']} Hz": {"achieved_hz": r["achieved_hz"],
                                          "achieved/target": r["achieved_hz"] / r["rate_hz"],
                                          "miss_fraction": r["miss_fraction"]} for r in hil.get("rates", [])}
        s["hil"]["free_running_steps_per_s"] = hil.get("free_running", {}).get("steps_per_s")
    smap = data.get("stability_map")
    if smap:
        s["stability_map"] = smap.get("summary")
    return s


def plot_all(data: dict[str, Any], out: Path) -> dict[str, str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..cosim.plotstyle import save_figure

    figures: dict[str, str] = {}
    markers = "os^vD<>ph*"
    m = data.get("dashboard_measurements")
    wp = data.get("cosim_work_precision")
    panels = []
    if m:
        panels.append(("kinematic, plain N=10 (this dashboard)", m["work_precision"]["runs"], "pointwise_error",
                       "max pointwise thrust error / peak"))
    for entry in (wp or {}).get("scenes", []):
        panels.append((f"{entry['scene']}, chordwise (the work-precision bench)", entry["runs"], "error",
                       f"relative error of {entry['metric']} (chaos floor {entry['chaos_floor']['estimate']:.1e})"))
    if panels:
        fig, axes = plt.subplots(1, len(panels), figsize=(6.2 * len(panels), 4.6), squeeze=False,
                                 constrained_layout=True)
        for ax, (title, runs, key, label) in zip(axes[0], panels):
            modes = sorted({r["mode"] for r in runs if key in r})
            for i, mode in enumerate(modes):
                rows = sorted((r for r in runs if r["mode"] == mode and key in r), key=lambda r: r["param"])
                ls = "--" if mode.startswith(("monolithic", "scipy")) else "-"
                ax.loglog([max(r[key], 1e-9) for r in rows], [r["time_s"] for r in rows], ls,
                          marker=markers[i % len(markers)], label=mode)
            ax.set_xlabel(label)
            ax.set_ylabel("run time (s)")
            ax.set_title(title, fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
        fig.suptitle("Work-precision per scene and coupling mode (dashed: references)")
        path = out / "dashboard_work_precision.png"
        save_figure(fig, path, dpi=100)
        figures["work_precision"] = path.name
    if m:
        cg = m["cost_growth"]
        fig, axes = plt.subplots(1, 2, figsize=(12, 4.4), constrained_layout=True)
        for key, ax, xlabel in (("by_n", axes[0], "N units"), ("by_duration", axes[1], "simulated duration (s)")):
            rows = cg[key]
            xs = [r["n_units"] if key == "by_n" else r["t_end_s"] for r in rows]
            for i, method in enumerate(METHODS):
                ax.loglog(xs, [r[method]["wall_s"] for r in rows], "--" if method in REFERENCES else "-",
                          marker=markers[i], label=method)
            ax.set_xlabel(xlabel)
            ax.set_ylabel("wall time (s)")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
        axes[0].set_title("cost growth with N (plain feather, 1 period of 1.5 s)")
        axes[1].set_title("cost growth with simulated duration (plain, N = 10)")
        path = out / "dashboard_cost_growth.png"
        save_figure(fig, path, dpi=100)
        figures["cost_growth"] = path.name
    s = data.get("summary", {})
    bars = []
    for name, row in (s.get("fmu_call_overhead") or {}).items():
        for key, label in (("fmu_me_derivative_us", "FMU ME derivative"), ("fmu_cs_do_step_1ms_us", "FMU CS doStep (1 ms)"),
                           ("casadi_call_from_python_us", "CasADi call from Python"),
                           ("casadi_buffer_call_us", "CasADi buffer call")):
            if row.get(key):
                bars.append((name, label, row[key]))
    opt, hil = s.get("optimizer"), s.get("hil")
    if bars or opt or hil:
        fig, axes = plt.subplots(1, 3, figsize=(15, 4.4), constrained_layout=True)
        if bars:
            names = sorted({b[0] for b in bars})
            labels = ["FMU ME derivative", "FMU CS doStep (1 ms)", "CasADi call from Python", "CasADi buffer call"]
            width = 0.8 / len(labels)
            for j, label in enumerate(labels):
                vals = [next((b[2] for b in bars if b[0] == n and b[1] == label), float("nan")) for n in names]
                axes[0].bar([i + j * width for i in range(len(names))], vals, width, label=label)
            axes[0].set_xticks([i + 0.4 - width / 2 for i in range(len(names))], names, fontsize=8)
            axes[0].set_yscale("log")
            axes[0].set_xlabel("feather model")
            axes[0].set_ylabel("µs per call (from Python)")
            axes[0].set_title("FMU call overhead")
            axes[0].legend(fontsize=7)
        if opt:
            items = [(k, v) for k, v in (("30 iterations", opt.get("optimization_wall_s", opt.get("estimated_30_iterations_wall_s"))),
                                         ("full sweep", opt.get("sweep_wall_s", opt.get("estimated_full_sweep_wall_s"))))
                     if v is not None]
            axes[1].bar([k for k, _ in items], [v for _, v in items], color=["C0", "C1"][: len(items)])
            for goal, x in ((60.0, 0), (120.0, 1)):
                axes[1].plot([x - 0.4, x + 0.4], [goal, goal], "k--", lw=1)
            axes[1].set_xlabel("task")
            axes[1].set_ylabel("wall time (s)")
            axes[1].set_title("optimizer and sweep (dashed: goals)" + (" — estimated" if "estimate" in opt["source"] else ""),
                              fontsize=9)
        if hil:
            rates = [(k, v) for k, v in hil.items() if isinstance(v, dict)]
            axes[2].bar([k for k, _ in rates], [v["achieved_hz"] for _, v in rates], color="C2", label="achieved")
            axes[2].plot(range(len(rates)), [float(k.split()[0]) for k, _ in rates], "k_", ms=30, mew=2, label="target")
            axes[2].set_xlabel("target loop rate (Hz)")
            axes[2].set_ylabel("loop rate (Hz)")
            axes[2].set_title("HIL loop rate over Modbus loopback")
            axes[2].legend(fontsize=8)
        path = out / "dashboard_overheads.png"
        save_figure(fig, path, dpi=100)
        figures["overheads"] = path.name
    return figures


def _fmt(v: Any, spec: str = ".3g") -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return format(v, spec) if math.isfinite(v) else str(v)
    return str(v)


def write_markdown(report: dict[str, Any], out: Path) -> Path:
    s = report["summary"]
    lines = [f"# featherstar benchmark dashboard{' (--quick)' if report['quick'] else ''}", "",
             f"{report['started']} on {report['machine']['platform']}, {report['machine']['cpus']} cores, load "
             f"{report['machine']['load_avg_1min_at_start']:.1f} → {report['machine'].get('load_avg_1min_at_end', float('nan')):.1f}; "
             f"total {report['total_s']:.0f} s. Every timing below is a ratio measured side by side in one process; "
             "absolute times move with the (shared) machine's load.", "", "## Benchmarks run", "",
             "| benchmark | status | wall (s) | outputs |", "|---|---|---|---|"]
    for name, b in report["benches"].items():
        status = "timed out" if b["timed_out"] else ("ok" if b["returncode"] == 0 else f"FAILED (rc {b['returncode']}, see logs/{name}.log)")
        lines.append(f"| {name} | {status} | {b['wall_s']:.0f} | {', '.join(b['outputs']) or '–'} |")
    for name in report.get("full_run_only", []):
        lines.append(f"| {Path(name).stem} | not run: full runs only (`python bench/{name}`) | – | – |")
    figs = report.get("figures", {})
    if "work_precision" in figs:
        lines += ["", "## Work-precision per scene and coupling mode", "",
                  f"![work-precision]({figs['work_precision']})", ""]
        goal = s.get("cosim_goal") or {}
        for scene, g in goal.items():
            if g:
                for key in ("vs_monolithic_casadi", "vs_monolithic_compiled"):
                    r = (g or {}).get(key) or {}
                    if r.get("ratio") is not None:
                        lines.append(f"- {scene}: fastest co-simulation within 1 % of the reference "
                                     f"({r['cosim']['mode']} {r['cosim']['param']:g}) takes {r['ratio']:.2f}× the "
                                     f"fastest equally accurate {key.replace('vs_', '').replace('_', ' ')} run.")
    if "cost_growth" in figs:
        lines += ["", "## Cost growth with N and with simulated duration", "", f"![cost growth]({figs['cost_growth']})", "",
                  "| N | strong / monolithic | strong / scipy | Jacobi / monolithic | Jacobi / scipy |", "|---|---|---|---|---|"]
        for n, r in (s.get("ratios_by_n") or {}).items():
            lines.append(f"| {n} | {_fmt(r.get('cosim-strong/monolithic-casadi'), '.2f')} | "
                         f"{_fmt(r.get('cosim-strong/scipy-solve_ivp'), '.2f')} | "
                         f"{_fmt(r.get('cosim-jacobi/monolithic-casadi'), '.2f')} | {_fmt(r.get('cosim-jacobi/scipy-solve_ivp'), '.2f')} |")
        ex = s.get("n_growth_exponent") or {}
        dx = s.get("duration_growth_exponent") or {}
        lines += ["", "Growth exponents (wall ∝ N^a over the N range; ∝ duration^b): " + "; ".join(
            f"{k} a = {ex.get(k, float('nan')):.2f}, b = {dx.get(k, float('nan')):.2f}" for k in METHODS) + "."]
    if "overheads" in figs:
        lines += ["", "## FMU call overhead, optimizer and sweep, HIL loop rate", "", f"![overheads]({figs['overheads']})", ""]
        for name, row in (s.get("fmu_call_overhead") or {}).items():
            lines.append(f"- {name}: one RHS through the FMU (ME, fmpy) {_fmt(row.get('fmu_me_derivative_us'))} µs vs the "
                         f"CasADi equations called from Python {_fmt(row.get('casadi_call_from_python_us'))} µs "
                         f"(ratio {_fmt(row.get('fmu/casadi_call_from_python'), '.2f')}) and CasADi's buffer call "
                         f"{_fmt(row.get('casadi_buffer_call_us'))} µs (ratio {_fmt(row.get('fmu/casadi_buffer_call'), '.2f')}); "
                         f"CS doStep of 1 ms {_fmt(row.get('fmu_cs_do_step_1ms_us'))} µs (bench/fmu_models.py).")
        for name, ratios in (s.get("fmu_vs_casadi_stroke_run") or {}).items():
            lines.append(f"- {name} under the stroke, wall time / direct CasADi integration: "
                         + ", ".join(f"{k} {_fmt(v, '.2f')}" for k, v in ratios.items()))
        opt = s.get("optimizer")
        if opt:
            if "estimate" in opt["source"]:
                lines.append(f"- optimizer ({opt['source']}): one evaluation {opt['evaluation_wall_s']:.1f} s, optimizer "
                             f"overhead {opt['optimizer_overhead_per_iteration_s'] * 1e3:.0f} ms per iteration → 30 "
                             f"iterations ≈ {opt['estimated_30_iterations_wall_s']:.0f} s (goal 60 s); simulation share "
                             f"{opt['estimated_simulation_share']:.1%}; full sweep ≈ {opt['estimated_full_sweep_wall_s']:.0f} s "
                             f"on {opt['sweep_workers']} workers (goal 120 s).")
                if "last_full_run" in opt:
                    lf = opt["last_full_run"]
                    lines.append(f"  Last full measurement in bench/results: 30 iterations {lf['optimization_wall_s']:.0f} s, "
                                 f"sweep {lf['sweep_wall_s']:.0f} s.")
            else:
                lines.append(f"- optimizer: {opt['iterations']} iterations {opt['optimization_wall_s']:.0f} s (simulation "
                             f"share {opt['simulation_share']:.1%}); sweep of {opt['sweep_runs']} runs {opt['sweep_wall_s']:.0f} s "
                             f"on {opt['sweep_workers']} workers.")
        hil = s.get("hil")
        if hil:
            lines.append("- HIL loop (3 Modbus transactions per step, loopback): " + ", ".join(
                f"{k}: {v['achieved_hz']:.0f} Hz ({v['achieved/target']:.0%} of target, {v['miss_fraction']:.0%} late)"
                for k, v in hil.items() if isinstance(v, dict))
                + f"; free running {_fmt(hil.get('free_running_steps_per_s'), '.0f')} steps/s.")
    if "stability_map.png" in {o for b in report["benches"].values() for o in b["outputs"]}:
        lines += ["", "## Stability map (weak couplings, test bed)", "", "![stability map](stability_map.png)", ""]
        lines += [f"- {line}" for line in (s.get("stability_map") or [])]
        limits = " / ".join(f"{factor:g}x ({coupling})" for coupling, factor in LOOP_STEP_PER_TIME_CONSTANT.items())
        lines += ["", f"The master refuses a fixed macro step longer than {limits} the fastest time constant on a feedback "
                  "loop (test bed: the servo's 5 ms load filter) and recording grids coarser than the shortest ramp "
                  f"/ {SAMPLES_PER_RAMP} (cosim/guards.py); the map runs with that check lifted. Edges and guards: "
                  "docs/stability.md."]
    other = [o for b in report["benches"].values() for o in b["outputs"]
             if o.endswith(".png") and o not in ("stability_map.png",)]
    if other:
        lines += ["", "## The benchmarks' own figures", ""] + [f"![{o}]({o})" for o in other]
    path = out / "dashboard.md"
    path.write_text("\n".join(lines) + "\n")
    return path
