"""`featherstar bench [--quick] [--out DIR]`: every benchmark in bench/, one JSON, one report.

The benchmarks are scripts in a repository checkout's `bench/` folder (they are not installed with
the package): `find_bench_dir` looks for it from the current directory upwards and says so when
there is none. Each script runs as its own process (`--quick` passed through, `--out` where the
script takes it; scripts that always write to bench/results have their new files copied), two at
a time on a 2-core machine, except the timing-sensitive HIL loop-rate bench, which runs alone.
Their JSON is collected as is. What they do not measure, the dashboard measures itself, in one
more process (`python -m cosim.dashboard --measure`), side by side in that process:

* the same ODE four ways: the co-simulation master (strong: ME FMU + CVODE; Jacobi: CS FMU at 1 ms),
  the monolithic CasADi model (`cosim.run_monolithic`: CVODES on CasADi's expression graph) and
  what a user would write instead: scipy `solve_ivp` (RK45, the default) calling the same CasADi
  equations from Python. Every timing is reported as a ratio to the monolithic model and to scipy;
* cost growth with N (plain feather) and with the simulated duration;
* a work-precision set for the kinematic scene with the plain feather (periodic, so errors are
  pointwise) against a compiled monolithic reference at rtol 1e-10;
* the cost of one RHS call of the CasADi equations from Python (numpy in, DM out; and CasADi's
  preallocated-buffer call), to set the FMU call overhead measured by bench/fmu_models.py against;
* in --quick mode, one real optimizer evaluation (the optimizer bench then only times the
  optimizer's own overhead on its analytic stand-in): the 30-iteration and sweep wall times
  are estimated from the two, and labelled as estimates.

Then `<out>/dashboard.json` (everything) and `<out>/dashboard.md` (the short report, with
dashboard_*.png figures and the benches' own figures) are written.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

from fmu_src.errors import FeatherstarError

__all__ = ["BenchError", "find_bench_dir", "run_dashboard", "register", "main"]


class BenchError(FeatherstarError):
    """The benchmark folder is missing, or the dashboard could not run."""


# ------------------------------------------------------------------------------------------------
# locating and running the benchmark scripts
# ------------------------------------------------------------------------------------------------

def find_bench_dir(start: Path | str | None = None) -> Path:
    """The `bench/` folder of the repository checkout containing `start` (default: the cwd)."""
    here = Path(start if start is not None else Path.cwd()).resolve()
    for folder in (here, *here.parents):
        bench = folder / "bench"
        if bench.is_dir() and (folder / "pyproject.toml").is_file() and bench_scripts(bench):
            return bench
    raise BenchError(
        f"no bench/ folder with benchmark scripts in {here} or any folder above it: the benchmarks "
        "live in a featherstar repository checkout, not in the installed package; run `featherstar "
        "bench` from inside a checkout (git clone ... && cd featherstar)")


def bench_scripts(bench: Path) -> list[Path]:
    """Every benchmark script: bench/*.py except this dashboard's own wrapper and private modules."""
    return sorted(p for p in bench.glob("*.py") if p.name != "dashboard.py" and not p.name.startswith("_"))


@dataclass(frozen=True)
class Plan:
    """How the dashboard runs one script. `quick_args` replace a bare --quick in quick mode."""

    quick_args: tuple[str, ...] = ("--quick",)
    full_args: tuple[str, ...] = ()
    alone: bool = False  # timing-sensitive: nothing else runs meanwhile
    expected_s: float = 60.0  # for scheduling the longest first


# Reduced invocations keep `featherstar bench --quick` within 5 minutes on the 2-core machine.
PLANS: dict[str, Plan] = {
    "cosim_work_precision.py": Plan(("--quick", "--scenes", "testbed"), expected_s=150),
    "fmu_models.py": Plan(("--quick", "--models", "feather-plain,feather-chordwise,servo"), expected_s=60),
    "optimizer_timing.py": Plan(("--quick", "--synthetic"), expected_s=20),
    "hil_loop_rate.py": Plan(("--quick",), alone=True, expected_s=30),
    "stability_map.py": Plan(("--quick",), expected_s=90),
}
MEASURE_EXPECTED_S = 90.0


@dataclass
class Task:
    name: str
    argv: list[str]
    log: Path
    alone: bool = False
    expected_s: float = 60.0
    writes_to: Path | None = None  # where the script writes when it takes no --out
    started: float = 0.0
    wall_s: float = 0.0
    returncode: int | None = None
    timed_out: bool = False
    outputs: list[str] = field(default_factory=list)


def _takes_out(script: Path) -> bool:
    return '"--out"' in script.read_text(errors="replace")


def make_tasks(bench: Path, out: Path, quick: bool, measure: bool = True) -> list[Task]:
    tasks = []
    logs = out / "logs"
    for script in bench_scripts(bench):
        plan = PLANS.get(script.name, Plan())
        args = list(plan.quick_args if quick else plan.full_args)
        writes_to = None
        if _takes_out(script):
            args += ["--out", str(out)]
        else:
            writes_to = bench / "results"
        tasks.append(Task(script.stem, [sys.executable, str(script), *args], logs / f"{script.stem}.log",
                          plan.alone, plan.expected_s, writes_to))
    if measure:
        argv = [sys.executable, "-m", "cosim.dashboard", "--measure", str(out)] + (["--quick"] if quick else [])
        tasks.append(Task("dashboard_measurements", argv, logs / "dashboard_measurements.log",
                          expected_s=MEASURE_EXPECTED_S))
    return tasks


def _new_files(folder: Path, since: float, suffixes: tuple[str, ...] = (".json", ".png")) -> list[Path]:
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.suffix in suffixes and p.stat().st_mtime >= since - 1e-3)


def run_tasks(tasks: list[Task], out: Path, *, jobs: int, timeout_s: float | None, env: dict[str, str],
              cwd: Path, log: Callable[[str], None]) -> None:
    """Run the tasks, `jobs` at a time (alone-tasks by themselves), longest expected first."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "logs").mkdir(exist_ok=True)
    alone = [t for t in tasks if t.alone]
    rest = sorted((t for t in tasks if not t.alone), key=lambda t: -t.expected_s)
    for batch, width in ([(alone, 1)] if alone else []) + [(rest, max(1, jobs))]:
        pending = list(batch)
        running: list[tuple[Task, subprocess.Popen, Any]] = []
        while pending or running:
            while pending and len(running) < width:
                task = pending.pop(0)
                task.started = time.time()
                fh = open(task.log, "w")
                log(f"start {task.name}: {' '.join(Path(a).name if i < 2 else a for i, a in enumerate(task.argv))}")
                proc = subprocess.Popen(task.argv, stdout=fh, stderr=subprocess.STDOUT, cwd=cwd, env=env)
                running.append((task, proc, fh))
            time.sleep(0.2)
            for entry in list(running):
                task, proc, fh = entry
                elapsed = time.time() - task.started
                if proc.poll() is None and timeout_s and elapsed > timeout_s:
                    proc.kill()
                    proc.wait()
                    task.timed_out = True
                if proc.poll() is not None:
                    fh.close()
                    task.returncode = proc.returncode
                    task.wall_s = time.time() - task.started
                    running.remove(entry)
                    _collect(task, out)
                    state = "timed out" if task.timed_out else ("ok" if task.returncode == 0 else f"FAILED (rc {task.returncode})")
                    log(f"done  {task.name}: {state} in {task.wall_s:.0f} s")


def _collect(task: Task, out: Path) -> None:
    """The files this task wrote: new since it started and named after it (`<name>.json`,
    `<name>_*.json`, `<name>.png`...; benches running at the same time write other names)."""
    source = task.writes_to if task.writes_to is not None else out
    files = [f for f in _new_files(source, task.started) if f.stem == task.name or f.stem.startswith(task.name + "_")]
    if source.resolve() != out.resolve():
        for f in files:
            shutil.copy2(f, out / f.name)
    task.outputs = sorted(f.name for f in files)


# ------------------------------------------------------------------------------------------------
# the dashboard's own measurements (run in their own process: python -m cosim.dashboard --measure)
# ------------------------------------------------------------------------------------------------

RTOL, ATOL = 1e-6, 1e-8
THRUST = "feather.thrust_N"


def _kinematic(n: int, t_end: float, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    return {"feather.morphology": "plain", "feather.n_units": n, "master.t_end_s": t_end,
            "metrics.settle_periods": 1, **(extra or {})}


def time_cosim(overrides: dict[str, Any]) -> dict[str, Any]:
    from .run import run_scene

    r = run_scene("kinematic", overrides, outputs=[THRUST])
    stats = r.summary["stats"]
    return {"wall_s": r.summary["wall_time_s"] - stats.get("build_s", 0.0), "build_s": stats.get("build_s", 0.0),
            "rhs_evals": stats.get("rhs_evals"), "macro_steps": stats.get("macro_steps"),
            "result": r}


def time_monolithic(overrides: dict[str, Any], rtol: float = RTOL, atol: float = ATOL,
                    compiled: bool = False, method: str = "adams") -> dict[str, Any]:
    from .monolithic import run_monolithic

    r = run_monolithic("kinematic", overrides, outputs=[THRUST], rtol=rtol, atol=atol, method=method,
                       compiled=compiled)
    return {"wall_s": r.summary["wall_time_s"], "compile_s": r.summary["stats"]["compile_s"], "result": r}


@dataclass
class _IvpResult:
    time: Any
    signals: dict[str, Any]
    summary: dict[str, Any]

    def __getitem__(self, name: str) -> Any:
        return self.signals[name]


def time_scipy(overrides: dict[str, Any], rtol: float = RTOL, atol: float = ATOL, method: str = "RK45") -> dict[str, Any]:
    """What a user would write instead: scipy's solve_ivp calling the CasADi equations from Python.

    The right-hand side is the scene composed into one ODE (the monolithic model's equations) as a
    CasADi Function, called with numpy arrays; its wall time includes building that function,
    as the monolithic model's includes building its integrator."""
    import casadi as ca
    import numpy as np
    from scipy.integrate import solve_ivp

    from .metrics import thrust_metrics, window
    from .monolithic import compose
    from .scene import load_scene

    started = time.perf_counter()
    scene = load_scene("kinematic").with_overrides(overrides)
    c = compose(scene, [THRUST])
    f = ca.Function("f", [c["t"], c["x"]], [c["xdot"]])
    out = ca.Function("y", [c["x"], c["t"]], [c["signals"][THRUST]])
    t_end = c["plan"].t_end_s
    grid = np.linspace(0.0, t_end, int(round(t_end / scene.master.output_interval_s)) + 1)
    calls = [0]

    def rhs(t: float, x: Any) -> Any:
        calls[0] += 1
        return np.asarray(f(t, x)).ravel()

    sol = solve_ivp(rhs, (0.0, t_end), c["x0"], method=method, rtol=rtol, atol=atol, t_eval=grid)
    if not sol.success:
        raise BenchError(f"scipy solve_ivp ({method}) failed: {sol.message}")
    thrust = np.asarray(out.map(len(grid))(sol.y, grid.reshape(1, -1))).ravel()
    wall = time.perf_counter() - started
    period = c["plan"].period_s
    a, b, k = window(float(grid[-1]), period, scene.metrics.settle_periods)
    summary = {"period_s": period, **thrust_metrics(grid, thrust, a, b, period, k)}
    return {"wall_s": wall, "rhs_evals": calls[0], "result": _IvpResult(grid, {THRUST: thrust}, summary)}


def _strip(entry: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in entry.items() if k != "result"}


METHODS: dict[str, Callable[[dict[str, Any]], dict[str, Any]]] = {
    "cosim-strong": lambda o: time_cosim({**o, "master.coupling": "strong", "master.method": "adams",
                                          "master.rtol": RTOL, "master.atol": ATOL}),
    "cosim-jacobi": lambda o: time_cosim({**o, "master.coupling": "jacobi", "master.step_s": 1e-3,
                                          "master.rtol": RTOL}),
    "monolithic-casadi": lambda o: time_monolithic(o),
    "scipy-solve_ivp": lambda o: time_scipy(o),
}
REFERENCES = ("monolithic-casadi", "scipy-solve_ivp")


def _ratios(row: dict[str, Any]) -> None:
    for method in ("cosim-strong", "cosim-jacobi"):
        for ref in REFERENCES:
            if method in row and ref in row and row[ref]["wall_s"] > 0:
                row[f"{method}/{ref}"] = row[method]["wall_s"] / row[ref]["wall_s"]


def _best(fn: Callable[[dict[str, Any]], dict[str, Any]], overrides: dict[str, Any],
          budget_s: float = 1.0, repeats: int = 3) -> dict[str, Any]:
    """The fastest of up to `repeats` runs (fewer once `budget_s` is spent): short runs on a shared
    machine are noisy, and the minimum is the least disturbed."""
    best: dict[str, Any] | None = None
    spent, n = 0.0, 0
    while n < repeats and (n == 0 or spent < budget_s):
        entry = _strip(fn(overrides))
        spent += entry["wall_s"]
        n += 1
        if best is None or entry["wall_s"] < best["wall_s"]:
            best = entry
    assert best is not None
    best["repeats"] = n
    return best


def cost_growth(ns: Sequence[int], durations: Sequence[float], log: Callable[[str], None]) -> dict[str, Any]:
    by_n, by_duration = [], []
    for n in ns:
        row: dict[str, Any] = {"n_units": n, "t_end_s": 1.5}
        for name, fn in METHODS.items():
            row[name] = _best(fn, _kinematic(n, 1.5))
        _ratios(row)
        log(f"N={n}: " + ", ".join(f"{m} {row[m]['wall_s']:.2f} s" for m in METHODS))
        by_n.append(row)
    for t_end in durations:
        row = {"n_units": 10, "t_end_s": t_end}
        for name, fn in METHODS.items():
            row[name] = _best(fn, _kinematic(10, t_end))
        _ratios(row)
        log(f"t_end={t_end:g} s: " + ", ".join(f"{m} {row[m]['wall_s']:.2f} s" for m in METHODS))
        by_duration.append(row)
    return {"scene": "kinematic", "morphology": "plain", "by_n": by_n, "by_duration": by_duration}


def work_precision(quick: bool, log: Callable[[str], None]) -> dict[str, Any]:
    """Kinematic scene, plain feather N = 10, 3 periods: run time against error per mode."""
    import numpy as np

    base = _kinematic(10, 4.5)
    ref = time_monolithic(base, rtol=1e-10, atol=1e-12, compiled=True)
    r_ref = ref["result"]
    peak = float(np.max(np.abs(r_ref[THRUST])))
    tr_ref = r_ref.summary["thrust_ratio"]
    tols = (1e-4, 1e-6) if quick else (1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
    steps = (4e-3, 1e-3) if quick else (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4)
    configs: list[tuple[str, float, Callable[[], dict[str, Any]]]] = []
    for tol in tols:
        configs.append(("strong-adams", tol, lambda tol=tol: time_cosim(
            {**base, "master.coupling": "strong", "master.method": "adams", "master.rtol": tol,
             "master.atol": tol * 1e-2})))
        configs.append(("monolithic-casadi", tol, lambda tol=tol: time_monolithic(base, rtol=tol, atol=tol * 1e-2)))
        configs.append(("scipy-solve_ivp-RK45", tol, lambda tol=tol: time_scipy(base, rtol=tol, atol=tol * 1e-2)))
    for coupling in ("jacobi", "gauss-seidel"):
        for h in steps:
            configs.append((coupling, h, lambda h=h, coupling=coupling: time_cosim(
                {**base, "master.coupling": coupling, "master.step_s": h, "master.rtol": 1e-6})))
    runs = []
    for mode, param, fn in configs:
        try:
            entry = fn()
            for _ in range(2 if entry["wall_s"] < 0.5 else 0):  # short runs: the fastest of three
                entry["wall_s"] = min(entry["wall_s"], fn()["wall_s"])
        except FeatherstarError as exc:
            runs.append({"mode": mode, "param": param, "failed": str(exc)})
            continue
        r = entry["result"]
        y = np.interp(r_ref.time, r.time, r[THRUST])
        row = {"mode": mode, "param": param, "time_s": entry["wall_s"],
               "thrust_ratio": r.summary["thrust_ratio"],
               "tr_error": abs(r.summary["thrust_ratio"] - tr_ref) / abs(tr_ref),
               "pointwise_error": float(np.max(np.abs(y - r_ref[THRUST])) / peak)}
        runs.append(row)
        log(f"work-precision {mode:<22} {param:<8g} {row['time_s']:6.2f} s  pointwise {row['pointwise_error']:.1e}  "
            f"TR {row['tr_error']:.1e}")
    return {"scene": "kinematic", "morphology": "plain", "n_units": 10, "t_end_s": 4.5,
            "reference": {"kind": "monolithic-compiled-adams", "rtol": 1e-10, "thrust_ratio": tr_ref,
                          "time_s": ref["wall_s"], "compile_s": ref["compile_s"]},
            "runs": runs}


def _open_me_fmu(model: Any) -> tuple[Any, str]:
    """The model's (cached) FMU, instantiated as Model Exchange and in continuous-time mode."""
    import tempfile

    import fmpy
    from fmpy import read_model_description
    from fmpy.fmi3 import FMU3Model

    from fmu_src.export import build_fmu

    path = build_fmu(model)
    md = read_model_description(str(path))
    folder = fmpy.extract(str(path), tempfile.mkdtemp(prefix="featherstar-dashboard-"))
    fmu = FMU3Model(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.modelExchange.modelIdentifier,
                    instanceName="dashboard")
    fmu.instantiate()
    fmu.enterInitializationMode(tolerance=RTOL, startTime=0.0)
    fmu.exitInitializationMode()
    fmu.updateDiscreteStates()
    fmu.enterContinuousTimeMode()
    return fmu, folder


def rhs_call_cost(n_calls: int, blocks: int = 3) -> dict[str, Any]:
    """µs per right-hand-side evaluation from Python, side by side in this process: the FMU's
    (Model Exchange, through fmpy: setContinuousStates + getContinuousStateDerivatives), the CasADi
    equations called with numpy arrays (what a user writes), and CasADi's preallocated-buffer call.
    Blocks are interleaved and the median taken, to shed bursts of load."""
    from ctypes import POINTER, c_double

    import numpy as np

    from fmu_src.catalog import MODELS

    out = {}
    for name in ("feather-plain", "feather-chordwise", "servo"):
        model = MODELS[name]()
        f = model.function()
        nx = model.x.numel()
        x = np.array(model.initial_state(), dtype=float) + 1e-3 * np.sin(np.arange(nx) + 1.0)
        u = np.full(model.u.numel(), 0.1)
        p = np.array(model.parameter_vector(), dtype=float)
        buf, call = f.buffer()
        res = [np.zeros(nx), np.zeros(model.y.numel())]
        for i, a in enumerate((x, u, p)):
            buf.set_arg(i, memoryview(a))
        for i, r in enumerate(res):
            buf.set_res(i, memoryview(r))
        fmu, folder = _open_me_fmu(model)
        dx = np.zeros(nx)
        px, pdx = x.ctypes.data_as(POINTER(c_double)), dx.ctypes.data_as(POINTER(c_double))
        times: dict[str, list[float]] = {"fmu_me_derivative_us": [], "casadi_call_from_python_us": [],
                                         "casadi_buffer_call_us": []}
        try:
            for _ in range(blocks):
                t0 = time.perf_counter()
                for _ in range(n_calls):
                    fmu.setContinuousStates(px, nx)
                    fmu.getContinuousStateDerivatives(pdx, nx)
                times["fmu_me_derivative_us"].append((time.perf_counter() - t0) / n_calls * 1e6)
                t0 = time.perf_counter()
                for _ in range(n_calls):
                    f(x, u, p)
                times["casadi_call_from_python_us"].append((time.perf_counter() - t0) / n_calls * 1e6)
                t0 = time.perf_counter()
                for _ in range(n_calls):
                    call()
                times["casadi_buffer_call_us"].append((time.perf_counter() - t0) / n_calls * 1e6)
        finally:
            fmu.terminate()
            fmu.freeInstance()
            shutil.rmtree(folder, ignore_errors=True)
        entry: dict[str, Any] = {k: float(np.median(v)) for k, v in times.items()}
        entry["fmu/casadi_call_from_python"] = entry["fmu_me_derivative_us"] / entry["casadi_call_from_python_us"]
        entry["fmu/casadi_buffer_call"] = entry["fmu_me_derivative_us"] / entry["casadi_buffer_call_us"]
        entry.update(states=int(nx), calls_per_block=n_calls, blocks=blocks)
        out[name] = entry
    return out


def optimizer_evaluation() -> dict[str, Any]:
    """One evaluation as the optimizer makes it (chordwise WR 7.5 test bed, CVODE Adams, 3 settling
    + 5 measured periods of 1.5 s), and one sweep run (2 + 3 periods)."""
    from .run import run_scene

    base = {"feather.morphology": "chordwise", "feather.width_ratio": 7.5, "master.method": "adams"}
    out = {}
    for label, periods in (("evaluation", 8), ("sweep_run", 5)):
        t0 = time.perf_counter()
        run_scene("testbed", {**base, "master.periods": periods}, outputs=[THRUST])
        out[f"{label}_wall_s"] = time.perf_counter() - t0
    return out


def measure(out: Path, quick: bool) -> dict[str, Any]:
    t0 = time.perf_counter()

    def log(msg: str) -> None:
        print(f"{time.perf_counter() - t0:7.1f}s {msg}", flush=True)

    # warm-up: load FMUs, CasADi and SUNDIALS once so the first timed run pays no import cost
    for fn in METHODS.values():
        fn(_kinematic(10, 0.05))
    report: dict[str, Any] = {
        "quick": quick, "rtol": RTOL, "atol": ATOL,
        "machine": {"cpus": os.cpu_count(), "load_avg_1min_at_start": os.getloadavg()[0],
                    "python": platform.python_version(), "platform": platform.platform()},
        "methods": {
            "cosim-strong": "featherstar master, strong coupling: ME FMU + CVODE Adams (rtol 1e-6)",
            "cosim-jacobi": "featherstar master, Jacobi: CS FMU (embedded Dormand-Prince) at 1 ms macro steps",
            "monolithic-casadi": "the same equations as one CasADi ODE, CVODES Adams on CasADi's VM (rtol 1e-6)",
            "scipy-solve_ivp": "what a user would write instead: scipy solve_ivp (RK45) calling the CasADi "
                               "equations from Python (rtol 1e-6)",
        },
    }
    report["rhs_call_cost"] = rhs_call_cost(1000 if quick else 5000, 3 if quick else 5)
    log("rhs call cost done")
    ns = (2, 5, 10) if quick else (2, 5, 10, 20)
    durations = (1.5, 4.5, 12.0) if quick else (1.5, 3.0, 6.0, 12.0, 24.0)
    report["cost_growth"] = cost_growth(ns, durations, log)
    report["work_precision"] = work_precision(quick, log)
    if quick:
        report["optimizer_evaluation"] = optimizer_evaluation()
        log(f"optimizer evaluation {report['optimizer_evaluation']}")
    report["machine"]["load_avg_1min_at_end"] = os.getloadavg()[0]
    report["total_s"] = time.perf_counter() - t0
    out.mkdir(parents=True, exist_ok=True)
    (out / "dashboard_measurements.json").write_text(json.dumps(report, indent=2, default=float) + "\n")
    log(f"wrote {out / 'dashboard_measurements.json'}")
    return report


# ------------------------------------------------------------------------------------------------
# the report
# ------------------------------------------------------------------------------------------------

def _load(out: Path, name: str) -> dict[str, Any] | None:
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

    figures: dict[str, str] = {}
    markers = "os^vD<>ph*"
    m = data.get("dashboard_measurements")
    wp = data.get("cosim_work_precision")
    panels = []
    if m:
        panels.append(("kinematic, plain N=10 (this dashboard)", m["work_precision"]["runs"], "pointwise_error",
                       "max pointwise thrust error / peak"))
    for entry in (wp or {}).get("scenes", []):
        panels.append((f"{entry['scene']}, chordwise (bench/cosim_work_precision.py)", entry["runs"], "error",
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
        fig.savefig(path, dpi=100)
        plt.close(fig)
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
        fig.savefig(path, dpi=100)
        plt.close(fig)
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
            axes[1].set_ylabel("wall time (s)")
            axes[1].set_title("optimizer and sweep (dashed: goals)" + (" — estimated" if "estimate" in opt["source"] else ""),
                              fontsize=9)
        if hil:
            rates = [(k, v) for k, v in hil.items() if isinstance(v, dict)]
            axes[2].bar([k for k, _ in rates], [v["achieved_hz"] for _, v in rates], color="C2", label="achieved")
            axes[2].plot(range(len(rates)), [float(k.split()[0]) for k, _ in rates], "k_", ms=30, mew=2, label="target")
            axes[2].set_ylabel("loop rate (Hz)")
            axes[2].set_title("HIL loop rate over Modbus loopback")
            axes[2].legend(fontsize=8)
        path = out / "dashboard_overheads.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
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
        lines += ["", "Edges and the cases that cannot be made stable: docs/stability.md."]
    other = [o for b in report["benches"].values() for o in b["outputs"]
             if o.endswith(".png") and o not in ("stability_map.png",)]
    if other:
        lines += ["", "## The benchmarks' own figures", ""] + [f"![{o}]({o})" for o in other]
    path = out / "dashboard.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def run_dashboard(quick: bool = False, out: Path | None = None, *, jobs: int = 2, timeout_s: float | None = None,
                  start: Path | None = None, log: Callable[[str], None] | None = None,
                  measure: bool = True) -> dict[str, Any]:
    """Run every benchmark and write dashboard.json and dashboard.md; returns the report.
    measure=False skips the dashboard's own measurements (tests of the plumbing)."""
    bench = find_bench_dir(start)
    root = bench.parent
    out = Path(out) if out is not None else bench / "results"
    out = out if out.is_absolute() else Path.cwd() / out
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    log = log or (lambda msg: print(f"{time.perf_counter() - t0:6.0f}s {msg}", flush=True))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")])))
    env.setdefault("MPLBACKEND", "Agg")
    tasks = make_tasks(bench, out, quick, measure)
    started = time.strftime("%Y-%m-%d %H:%M:%S")
    machine = {"cpus": os.cpu_count(), "load_avg_1min_at_start": os.getloadavg()[0],
               "python": platform.python_version(), "platform": platform.platform()}
    run_tasks(tasks, out, jobs=jobs, timeout_s=timeout_s, env=env, cwd=root, log=log)
    machine["load_avg_1min_at_end"] = os.getloadavg()[0]
    data: dict[str, Any] = {}
    benches: dict[str, Any] = {}
    for task in tasks:
        benches[task.name] = {"argv": [Path(task.argv[0]).name, *task.argv[1:]], "returncode": task.returncode,
                              "timed_out": task.timed_out, "wall_s": task.wall_s, "outputs": task.outputs,
                              "log": str(task.log.relative_to(out))}
        for name in task.outputs:
            if name.endswith(".json"):
                loaded = _load(out, name)
                if loaded is not None:
                    data[Path(name).stem] = loaded
    if quick and "optimizer_timing" not in data:  # the last real optimizer measurement, labelled as such
        last = _load(bench / "results", "optimizer_timing.json")
        if last is not None:
            data["optimizer_timing"] = last
    report = {"quick": quick, "started": started, "machine": machine, "bench_dir": str(bench), "benches": benches,
              "total_s": time.perf_counter() - t0}
    report["summary"] = derive(data, quick)
    data["summary"] = report["summary"]
    report["figures"] = plot_all(data, out)
    report["results"] = data
    report["total_s"] = time.perf_counter() - t0
    (out / "dashboard.json").write_text(json.dumps(report, indent=2, default=float) + "\n")
    md = write_markdown(report, out)
    log(f"wrote {out / 'dashboard.json'} and {md} ({report['total_s']:.0f} s)")
    failed = [n for n, b in benches.items() if b["returncode"] != 0]
    if failed:
        log(f"{len(failed)} benchmark(s) failed or timed out: {', '.join(failed)} (logs in {out / 'logs'})")
    return report


# ------------------------------------------------------------------------------------------------
# command line
# ------------------------------------------------------------------------------------------------

def _cmd_bench(args: argparse.Namespace) -> int:
    report = run_dashboard(args.quick, args.out, jobs=args.jobs, timeout_s=args.timeout)
    return 0 if all(b["returncode"] == 0 for b in report["benches"].values()) else 1


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="reduced benchmarks (under 5 minutes on 2 cores)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: bench/results)")
    parser.add_argument("--jobs", type=int, default=2, help="benchmarks run at once (default 2; HIL always alone)")
    parser.add_argument("--timeout", type=float, default=None, help="stop a benchmark after this many seconds")


def register(subparsers: Any) -> None:
    """Adds `featherstar bench` to the featherstar command line."""
    parser = subparsers.add_parser(
        "bench", help="run every benchmark in bench/ and write one JSON and a markdown report",
        description="Run every benchmark script of the repository checkout's bench/ folder (found from the "
                    "current directory), collect their JSON, add the dashboard's own side-by-side measurements "
                    "and write dashboard.json and dashboard.md with plots.")
    add_arguments(parser)
    parser.set_defaults(func=_cmd_bench)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="featherstar bench", description=__doc__.splitlines()[0])
    add_arguments(parser)
    parser.add_argument("--measure", type=Path, metavar="OUT", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    try:
        if args.measure is not None:
            measure(args.measure, args.quick)
            return 0
        return _cmd_bench(args)
    except FeatherstarError as exc:
        print(f"featherstar bench: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
