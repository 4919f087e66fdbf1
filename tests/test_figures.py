"""Every figure a command or bench script writes, rendered on tiny inputs and looked at.

The writers are found, not listed by hand: every figure goes through
`featherstar.cosim.plotstyle.save_figure` (a raw `savefig` elsewhere fails
`test_every_figure_goes_through_the_style`), and every function that calls it (or a module's
`_save`-like helper that does) must have a case in CASES here, so a new figure cannot escape.
Each case renders its writer while `plotstyle.observe()` collects the Figure objects, and
`problems` checks what a reader needs: labels (with a unit where the quantity has one, no code
names), a title, panels with data, legends whose entries all show a handle, integer ticks on
counts, bars from zero, a y scale not squashed by a start transient.
"""
from __future__ import annotations

import ast
import importlib.util
import json
import math
import re
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Callable

import numpy as np
import pytest
from matplotlib.container import BarContainer

from featherstar.cosim import plotstyle

ROOT = Path(__file__).resolve().parents[1]
SOURCES = [ROOT / d for d in ("src", "fmu_src", "cosim", "optimizer", "hil", "bench")]
RESULTS = ROOT / "docs" / "results"

#: A label with its unit in brackets or parentheses.
UNIT = re.compile(r"[\(\[][^\)\]]*[\)\]]")
#: Quantities that have no unit (ratios, counts, normalized or relative values, names).
DIMENSIONLESS = re.compile(
    r"\b(TR|WR|LR|KC|ratio|normali[sz]ed|relative|fraction|error|number|count|log10|iteration|period|"
    r"evaluation|repeat|morphology|feather|coupling|mode|N units|method|scene|model|rule|seed|task|FMU|coefficient)s?\b|/",
    re.IGNORECASE)
MATH = re.compile(r"\$[^$]*\$")
#: Other libraries' API names a reader looks up as written (scipy's solve_ivp, fmpy's simulate_fmu).
FOREIGN = re.compile(r"\b(solve_ivp|simulate_fmu)\b")


# ---------------------------------------------------------------- finding the writers

def _python_files() -> list[Path]:
    return [p for folder in SOURCES for p in sorted(folder.rglob("*.py")) if p.name != "plotstyle.py"]


def _calls(node: ast.AST) -> set[str]:
    names = set()
    for sub in ast.walk(node):
        if isinstance(sub, ast.Call):
            f = sub.func
            names.add(f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else "")
    return names


def writers() -> set[str]:
    """"path::function" of every function that writes a figure through save_figure: the direct
    callers, except a module's saving helpers (they take the figure, `_save(fig, path)`), which
    stand for the functions of the module that call them."""
    found = set()
    for path in _python_files():
        text = path.read_text(encoding="utf-8")
        if "save_figure" not in text:
            continue
        functions = {n.name: n for n in ast.walk(ast.parse(text)) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}
        calls = {name: _calls(node) for name, node in functions.items()}
        direct = {name for name, c in calls.items() if "save_figure" in c}
        helpers = {h for h in direct if any(a.arg == "fig" for a in functions[h].args.args)}
        users = {name for name, c in calls.items() if c & helpers and name not in helpers}
        rel = path.relative_to(ROOT).as_posix()
        found |= {f"{rel}::{name}" for name in (direct - helpers) | users}
        outside = ast.parse(text)
        outside.body = [n for n in outside.body if not isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))]
        if "save_figure" in _calls(outside):
            found.add(f"{rel}::<module>")                  # a figure written by a script's top level
    return found


def test_every_figure_goes_through_the_style():
    raw = [f"{p.relative_to(ROOT)}:{k}" for p in _python_files()
           for k, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if ".savefig(" in line]
    assert not raw, "figures written around featherstar.cosim.plotstyle.save_figure:\n" + "\n".join(raw)


def test_every_figure_writer_has_a_case():
    found = writers()
    assert len(found) >= 15, f"the finder found too few writers: {sorted(found)}"
    assert found == set(CASES), (f"writers without a case: {sorted(found - set(CASES))}; "
                                 f"cases without a writer: {sorted(set(CASES) - found)}")


# ---------------------------------------------------------------- what a figure must carry

def _text(s: str) -> str:
    return FOREIGN.sub("", MATH.sub("", s))


def _is_data_line(line: Any, ax: Any) -> bool:
    return line.get_transform() == ax.transData and line.get_visible()


def _finite_data(ax: Any) -> bool:
    for line in ax.get_lines():
        if _is_data_line(line, ax):
            y = np.asarray(line.get_ydata(), float)
            if y.size and np.isfinite(y).any():
                return True
    for patch in ax.patches:
        if patch.get_data_transform() == ax.transData and np.isfinite(patch.get_height()) and patch.get_height() != 0:
            return True
    for coll in ax.collections:
        offsets = np.asarray(coll.get_offsets(), float)
        if (offsets.size and np.isfinite(offsets).any()) or any(len(p.vertices) for p in coll.get_paths()):
            return True
    return bool(ax.images)


def _legend_problems(ax: Any, where: str) -> list[str]:
    legend = ax.get_legend()
    if legend is None:
        return []
    out = []
    shown = {t.get_text() for t in legend.get_texts()}
    for artist, label in zip(*ax.get_legend_handles_labels()):
        if label in shown and isinstance(artist, BarContainer) and not any(np.isfinite(p.get_height()) for p in artist):
            out.append(f"{where}: legend entry {label!r} stands for no bar")
    handles = list(legend.legend_handles)
    for handle, text in zip(handles, legend.get_texts()):
        label = text.get_text()
        if not label.strip():
            out.append(f"{where}: a legend entry without text")
        if "_" in _text(label):
            out.append(f"{where}: code name in the legend: {label!r}")
        if handle is None or not plotstyle._legend_handle_visible(handle):
            out.append(f"{where}: legend entry {label!r} has no visible handle")
    return out


def _siblings_labelled(ax: Any, which: str) -> bool:
    """The axis is labelled by a panel it shares it with: sharex/sharey, or a panel in the same
    column (x) or row (y) with the same limits, as in a stack of time traces."""
    group = ax.get_shared_x_axes() if which == "x" else ax.get_shared_y_axes()
    if any((a.get_xlabel() if which == "x" else a.get_ylabel()).strip() for a in group.get_siblings(ax)):
        return True
    box = ax.get_position()
    for other in ax.figure.axes:
        o = other.get_position()
        if which == "x" and other.get_xlabel().strip() and np.allclose([o.x0, o.x1], [box.x0, box.x1], atol=0.02) \
                and np.allclose(other.get_xlim(), ax.get_xlim()):
            return True
        if which == "y" and other.get_ylabel().strip() and np.allclose([o.y0, o.y1], [box.y0, box.y1], atol=0.02) \
                and np.allclose(other.get_ylim(), ax.get_ylim()):
            return True
    return False


def _label_problems(label: str, where: str) -> list[str]:
    out = []
    if "_" in _text(label):
        out.append(f"{where}: code name in the label {label!r}")
    if not UNIT.search(label) and not DIMENSIONLESS.search(label) and "%" not in label:
        out.append(f"{where}: no unit in (…) or […] in the label {label!r}")
    return out


def problems(fig: Any) -> list[str]:
    """What a reader would miss in `fig` (empty when it carries everything)."""
    fig.canvas.draw()
    out = []
    sup = fig._suptitle.get_text() if getattr(fig, "_suptitle", None) else ""
    titles = [sup] + [ax.get_title(loc) for ax in fig.axes for loc in ("center", "left", "right")]
    if not any(t.strip() for t in titles):
        out.append("no title or suptitle")
    out += [f"code name in the title {t!r}" for t in titles if "_" in _text(t)]
    for k, ax in enumerate(fig.axes):
        if not ax.get_visible() or not ax.axison:
            continue
        where = f"axes {k} ({ax.get_title() or ax.get_ylabel()!r})"
        twin = any(a is not ax and a.bbox.bounds == ax.bbox.bounds for a in fig.axes)
        if not _finite_data(ax) and not twin:
            out.append(f"{where}: an empty panel (no artist with finite data)")
        for which, label in (("x", ax.get_xlabel()), ("y", ax.get_ylabel())):
            if label.strip():
                out += _label_problems(label, f"{where} {which} label")
            elif not _siblings_labelled(ax, which) and not (which == "x" and twin):
                out.append(f"{where}: no {which} label")
        out += _legend_problems(ax, where)
        for which, label, ticks, scale, lim in (
                ("x", ax.get_xlabel(), ax.get_xticks(), ax.get_xscale(), ax.get_xlim()),
                ("y", ax.get_ylabel(), ax.get_yticks(), ax.get_yscale(), ax.get_ylim())):
            shown = [t for t in ticks if min(lim) - 1e-9 <= t <= max(lim) + 1e-9]
            if plotstyle.DISCRETE.search(label) and scale == "linear" and any(abs(t - round(t)) > 1e-9 for t in shown):
                out.append(f"{where}: fractional ticks on the count axis {label!r}: {shown}")
        for container in ax.containers:
            heights = [p.get_height() for p in getattr(container, "patches", [])]
            heights = [h for h in heights if np.isfinite(h)]
            if heights and min(heights) >= 0 and ax.get_yscale() == "linear" and ax.get_ylim()[0] > 0:
                out.append(f"{where}: bar chart's y axis starts at {ax.get_ylim()[0]:.3g}, not 0")
        if ax.get_yscale() == "linear":
            ys = [np.asarray(l.get_ydata(), float) for l in ax.get_lines() if _is_data_line(l, ax)]
            y = np.concatenate(ys) if ys else np.array([])
            y = y[np.isfinite(y)]
            if y.size >= 50:
                lo, hi = np.percentile(y, [5, 95])
                span = abs(ax.get_ylim()[1] - ax.get_ylim()[0])
                if hi > lo and (hi - lo) < 0.05 * span:
                    out.append(f"{where}: the bulk of the data fills {100 * (hi - lo) / span:.1f} % of the y axis "
                               "(squashed by a transient?)")
    return out


def test_the_checks_see_a_bad_figure():
    """The checker is not blind: a figure with each fault is reported for each."""
    import matplotlib.pyplot as plt

    fig, (a, b, c) = plt.subplots(3, 1)
    t = np.linspace(0, 10, 200)
    y = np.sin(t)
    y[0] = 1e3                                        # a start transient
    a.plot(t, y, label="thrust_N")                    # code name in a legend
    a.plot([], [], ls="none", label="ghost")           # an entry with nothing to show
    a.bar([], [], label="proxy")                      # a bar entry for no bar
    a.legend()
    a.set_ylabel("thrust")                            # no unit
    b.bar([1, 2], [1.5, 1.6])
    b.set_ylim(1.4, 1.7)
    b.set_xlabel("period")
    b.set_xticks([1, 1.5, 2])
    b.set_ylabel("TR")
    c.set_xlabel("time (s)")
    c.set_ylabel("thrust (mN)")                       # an empty panel
    found = "\n".join(problems(fig))
    for fault in ("no title", "code name in the legend", "no visible handle", "stands for no bar", "no unit", "no x label",
                  "starts at 1.4", "fractional ticks", "an empty panel", "squashed"):
        assert fault in found, f"{fault!r} not reported in:\n{found}"
    plt.close(fig)


def test_the_style_finishes_a_figure():
    """save_figure drops handle-less legend entries, starts bars at zero and makes count ticks integral."""
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(2, 1)
    a.plot([1, 2, 3], [1, 2, 3], label="drawn")
    a.plot([], [], ls="none", label="nothing to show")
    a.bar([1, 2], [math.nan, math.nan], label="bars of NaN")
    a.legend()
    b.bar([1, 2, 3], [1.5, 1.6, 1.55])
    b.set_ylim(1.4, 1.7)
    b.set_xlabel("iteration")
    plotstyle.finish(fig)
    fig.canvas.draw()
    assert [t.get_text() for t in a.get_legend().get_texts()] == ["drawn"]
    assert b.get_ylim()[0] == 0
    assert all(float(x).is_integer() for x in b.get_xticks())
    plt.close(fig)


def test_robust_limits_clip_a_transient_only():
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    t = np.linspace(0, 6, 600)
    y = np.sin(4 * t)
    assert not plotstyle.robust_ylim(ax, y)                   # nothing to clip
    y[:10] = 50.0                                              # a start transient
    assert plotstyle.robust_ylim(ax, y)
    assert ax.get_ylim()[1] < 2
    assert plotstyle.robust_ylim(ax, y, inside=t > 3)          # the metric window's range
    plt.close(fig)


# ---------------------------------------------------------------- the cases

def _bench(name: str) -> Any:
    """A bench script as a module (they are scripts, not installed)."""
    path = ROOT / "bench" / f"{name}.py"
    sys.path.insert(0, str(path.parent))
    try:
        spec = importlib.util.spec_from_file_location(f"bench_{name}", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module          # dataclasses look their module up
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(path.parent))
    return module


def _json(name: str) -> dict:
    return json.loads((RESULTS / f"{name}.json").read_text(encoding="utf-8"))


def _run_result(*, complete: bool = True, excluded: bool = False, robot: bool = False, transient: bool = False) -> Any:
    t = np.linspace(0, 6, 1200)
    thrust = 0.004 * np.sin(2 * np.pi * t / 1.5) + 0.001
    if transient:
        thrust[:20] = 0.5
    signals = {"feather.thrust": thrust, "stroke.angle": 0.5 * np.sin(2 * np.pi * t / 1.5)}
    metrics = SimpleNamespace(thrust="feather.thrust", angle="stroke.angle",
                              position="body.x" if robot else None, speed="body.v" if robot else None)
    if robot:
        signals |= {"body.x": 0.01 * t, "body.v": 0.01 + 0.001 * np.sin(t)}
    block = SimpleNamespace(settings={"options": {"morphology": "chordwise"}}, overrides={})
    summary = {"thrust_ratio": 1.4, "mean_thrust_N": 0.001, "window_s": [3.0, 6.0], "period_s": 1.5,
               "per_period_thrust_ratio": [1.3, 1.5]}
    if excluded:
        summary["validity"] = {"invalid_periods": [{"period": 2, "start_s": 4.5, "reasons": ["load cell stale"]}]}
    if not complete:
        summary["incomplete_reason"] = "a period was excluded"
    if robot:
        summary["mean_speed_m_s"] = 0.01
    return SimpleNamespace(scene=SimpleNamespace(name="testbed", blocks=[block], metrics=metrics), summary=summary,
                           time=t, signals=signals, complete=complete)


def _evaluations(n: int = 6) -> tuple[list, list, list]:
    names = ["t_up_s", "log10_up_down"]
    ev = [{"thrust_ratio": 1 + 0.1 * k, "params": {"t_up_s": 0.2 + 0.01 * k, "log10_up_down": 0.1 * k}} for k in range(n)]
    est = [None] + ev[1:]
    return ev, est, names


def _validation_rows() -> list[dict]:
    return [{"morphology": m, "controller": c, "thrust_ratio": 1.2 + k, "thrust_ratio_sd": 0.05,
             "mean_thrust_N": 0.002, "mean_thrust_sd_N": 0.0002}
            for m in ("plain", "chordwise") for k, c in enumerate(("best", "baseline", "worst"))]


def _sweep_table(normalized: bool) -> list[dict]:
    return [{"family": f, "ratio": r, "thrust_ratio": 1 + 0.1 * r, "mean_thrust_N": 0.001 * r,
             "normalized_thrust": r / 5 if normalized else math.nan}
            for f, ratios in (("chordwise", (5.5, 7.5, 9.5)), ("spanwise", (1.5, 2.0, 2.5))) for r in ratios]


def _plot_run(tmp: Path) -> None:
    from featherstar.cosim.swimmer.report import plot_run

    for k, kwargs in enumerate(({}, {"complete": False, "excluded": True}, {"robot": True, "transient": True})):
        plot_run(_run_result(**kwargs), tmp / f"run{k}.png")


def _sweep(tmp: Path) -> None:
    from featherstar.optimizer.figures import sweep_figure

    for normalized in (True, False):
        sweep_figure(_sweep_table(normalized), ["thrust_ratio", "normalized_thrust"], tmp / f"sweep{normalized}.png")


def _progress(tmp: Path) -> None:
    from featherstar.optimizer.figures import progress_figure

    progress_figure(*_evaluations(), tmp / "p.png")
    progress_figure(*_evaluations(), tmp / "q.png", title="Fig. 6: optimizer progress, testbed (simulation)")


def _validation(tmp: Path) -> None:
    from featherstar.optimizer.figures import validation_figure

    validation_figure(_validation_rows(), tmp / "v.png")


def _fit(tmp: Path) -> None:
    from featherstar.optimizer.calibration.cli import _fit_figure

    bins = np.linspace(0, 3, 60)
    result = SimpleNamespace(bin_times_s=bins, measured_N=np.array([0.003 * np.sin(bins), 0.003 * np.cos(bins)]),
                             simulated_N=np.array([0.003 * np.sin(bins)]), rms_residual_N=0.0004, r_squared=0.93)
    _fit_figure(result, ["run-1", "run-2"], tmp / "fit.png", "plate")


def _symmetric() -> dict:
    t = np.linspace(0, 6, 600)
    return {f: {"time_s": t, "thrust_N": 0.003 * np.sin(4 * t) + 0.001, "angle_rad": 0.5 * np.sin(4 * t),
                "thrust_ratio": 1.2 + k, "thrust_ratio_sd": 0.05} for k, f in enumerate(("plain", "chordwise", "spanwise"))}


def _paper(function: str) -> Callable[[Path], None]:
    def case(tmp: Path) -> None:
        from featherstar.optimizer.paper import figures
        from featherstar.optimizer.paper.plan import fig7_key

        if function == "fig3_sweep":
            figures.fig3_sweep(_sweep_table(True), tmp / "fig3.png")
            figures.fig3_sweep(_sweep_table(False), tmp / "fig3n.png")
        elif function == "fig5_symmetric":
            figures.fig5_symmetric(_symmetric(), tmp / "fig5.png")
        elif function == "fig7_strokes":
            res = SimpleNamespace(fig7_periods_s=(1.5,), fig7_width_ratios=(7.5,), fig7_length_ratios=(2.0,))
            stroke = {"t_up_s": 0.2, "t_hold_up_s": 0.5, "t_down_s": 0.3, "t_hold_down_s": 0.5}
            studies = {fig7_key(f, r, 1.5): {"stroke": stroke, "estimated_thrust_ratio": 1.5}
                       for f, r in (("chordwise", 7.5), ("spanwise", 2.0))}
            figures.fig7_strokes(studies, res, tmp / "fig7.png")
        elif function == "fig9_robot":
            t = np.linspace(0, 10, 300)
            robot = {f"{f}-{c}": {"time_s": t, "position_m": 0.01 * t * (k + 1), "speed_m_s": 0.01 + 0 * t,
                                  "mean_speed_m_s": 0.01 * (k + 1)}
                     for f in ("plain", "chordwise", "spanwise") for k, c in enumerate(("best", "baseline", "worst"))}
            figures.fig9_robot(robot, tmp / "fig9.png")
    return case


def _dashboard(tmp: Path) -> None:
    from featherstar.dashboard.report import METHODS, plot_all

    runs = [{"mode": m, "param": p, "pointwise_error": 10.0 ** -p, "error": 10.0 ** -p, "time_s": 0.1 * p}
            for m in ("strong", "jacobi") for p in (1, 2, 3)]
    growth = {"by_n": [{"n_units": n, **{m: {"wall_s": 0.01 * n} for m in METHODS}} for n in (5, 10, 20)],
              "by_duration": [{"t_end_s": d, **{m: {"wall_s": 0.01 * d} for m in METHODS}} for d in (1, 2, 4)]}
    data = {"dashboard_measurements": {"work_precision": {"runs": runs}, "cost_growth": growth},
            "cosim_work_precision": {"scenes": [{"scene": "testbed", "runs": runs, "metric": "TR",
                                                 "chaos_floor": {"estimate": 1e-3}}]},
            "summary": {"fmu_call_overhead": {"plain N=10": {"fmu_me_derivative_us": 20.0, "fmu_cs_do_step_1ms_us": 40.0},
                                               "chordwise N=10": {"fmu_me_derivative_us": 30.0, "casadi_buffer_call_us": 2.0}},
                        "optimizer": {"optimization_wall_s": 50.0, "sweep_wall_s": 100.0, "source": "measured"},
                        "hil": {"50 Hz": {"achieved_hz": 49.5}, "100 Hz": {"achieved_hz": 98.0}}}}
    plot_all(data, tmp)


def _bench_case(name: str) -> Callable[[Path], None]:
    def case(tmp: Path) -> None:
        m = _bench(name)
        if name == "bench_calibration":
            bins = np.linspace(0, 3, 60)
            fit = SimpleNamespace(bin_times_s=bins, measured_N=np.array([0.003 * np.sin(bins)] * 3),
                                  simulated_N=np.array([0.003 * np.sin(bins)]), r_squared=0.95)
            m.plot(fit, tmp / "c.png", "chordwise feather, offline\nfitted vs hidden: 3 %; R² 0.95")
        elif name == "bench_loop_prior":
            d = _json(name)
            m._figure(d["studies"], d["target_thrust_ratio"], d["gain_target_thrust_ratio"], d["baseline_thrust_ratio"],
                      tmp / "p.png")
        elif name == "flap_mechanisms":
            period = {"t_s": list(np.linspace(0, 1.5, 100)), "fold_rad": list(0.3 * np.sin(np.linspace(0, 6, 100))),
                      "thrust_N": list(0.002 * np.sin(np.linspace(0, 6, 100)))}
            results = {n: {"thrust_ratio": 1.5, "last_period": period} for n in ("supported", "free root part")}
            m.plot(results, m.Stroke(), tmp / "f.png")
        elif name == "wake_memory":
            m.plot(_json(name), {"quasi-steady": None}, m.RigidPlate(), tmp / "w.png")
        elif name == "hil_loop_rate":
            rates = [{"rate_hz": 50, "miss_fraction": 0.01}, {"rate_hz": 100, "miss_fraction": 0.05}]
            m.plot({"rates": rates}, {50: list(np.linspace(1, 5, 40)), 100: list(np.linspace(1, 12, 40))}, tmp)
        elif name == "stability_map":
            def weak(edge: float) -> dict:
                return {"bounded_edge_s": edge, "checks_edge_s": edge / 2, "bounded_edge_is_lower_bound": False,
                        "checks_edge_is_lower_bound": True}
            cells = [{"axis": "N", "morphology": "plain", "n_units": n, "contact_factor": 1,
                      "weak": {c: weak(0.002 * n) for c in m.COUPLINGS}} for n in (5, 10, 20)]
            m.plot({"cells": cells}, tmp / "s.png")
        elif name == "cosim_work_precision":
            runs = [{"mode": mo, "param": p, "error": 10.0 ** -p, "early_error": 10.0 ** -p, "time_s": 0.1 * p}
                    for mo in ("strong", "jacobi") for p in (1, 2, 3)]
            m.plot({"scenes": [{"scene": "testbed", "metric": "TR", "runs": runs, "chaos_floor": {"estimate": 1e-3}}]},
                   tmp / "w.png")
        elif name == "bench_model_form_calibration":
            m.plot(_json(name)["cases"], tmp / "f.png")
        elif name == "bench_timed_optimize":
            m.plot(_json("timed_optimize_load"), tmp / "o.png")
        elif name == "bench_timed_load":
            m.plot(_json("timed_vs_streaming_load"), tmp / "l.png")
        elif name == "mixed_coupling":
            m.plot(_json(name), tmp)
        elif name == "_peers_report":
            m.plot(_json("peers"), tmp / "peers.png")
        else:
            m.plot(_json(name), tmp / f"{name}.png")
    return case


CASES: dict[str, Callable[[Path], None]] = {
    "cosim/swimmer/report.py::plot_run": _plot_run,
    "optimizer/figures.py::sweep_figure": _sweep,
    "optimizer/figures.py::progress_figure": _progress,
    "optimizer/figures.py::validation_figure": _validation,
    "optimizer/calibration/cli.py::_fit_figure": _fit,
    **{f"optimizer/paper/figures.py::{f}": _paper(f) for f in ("fig3_sweep", "fig5_symmetric", "fig7_strokes", "fig9_robot")},
    "bench/dashboard/report.py::plot_all": _dashboard,
    "bench/bench_calibration.py::plot": _bench_case("bench_calibration"),
    "bench/bench_loop_prior.py::_figure": _bench_case("bench_loop_prior"),
    **{f"bench/{n}.py::plot": _bench_case(n) for n in (
        "_peers_report", "bench_model_form_calibration", "bench_timed_load", "bench_timed_optimize", "cosim_work_precision", "drag_convergence", "feather_speed", "flap_mechanisms", "fmu_models",
        "hil_loop_rate", "mixed_coupling", "optimizer_speed", "stability_map", "wake_memory")},
}


@pytest.mark.parametrize("writer", sorted(CASES))
def test_every_figure_reads_without_the_code(writer, tmp_path):
    with plotstyle.observe() as seen:
        CASES[writer](tmp_path)
    assert seen, f"{writer} wrote no figure through save_figure"
    found = [f"{path.name}: {p}" for fig, path in seen for p in problems(fig)]
    assert not found, f"{writer}:\n" + "\n".join(found)
    assert all(path.stat().st_size > 0 for _, path in seen)


def test_a_sweep_column_that_cannot_be_computed_says_why(tmp_path, capsys):
    """The synthetic plain feather's reference runs make no thrust: the normalized thrust is
    undefined for every geometry, and the console, summary.json and the figure each say why."""
    from featherstar.optimizer.cli import main

    with plotstyle.observe() as seen:
        assert main(["sweep", "synthetic:plain", "--family", "spanwise", "--out", str(tmp_path), "--no-progress",
                     "--workers", "1"]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    reason = summary["normalized_thrust_undefined"]
    assert "mN" in reason and "reference" in reason
    assert reason in capsys.readouterr().out
    ((fig, _),) = seen
    title = " ".join(fig._suptitle.get_text().split())
    assert "not drawn: normalized thrust" in title and reason in title
    assert not any("normalized" in ax.get_ylabel() for ax in fig.axes)
