"""FMU build time, per-step FMU cost, and FMU vs direct CasADi integration under the stroke.

1. Build time per model: cold (`build_fmu(force=True)` into a temporary FEATHERSTAR_CACHE) and
   cached (the second call, which only fingerprints the model and finds the file). With --quick
   only servo, robot and feather-plain are built cold (the chordwise feather alone takes ~40 s);
   the others are taken from the user's cache (built there if missing) and copied into the
   temporary cache, so that their cached call is timed the same way.
2. Per-step FMU cost, measured from Python through fmpy (so every figure includes fmpy's ctypes
   call and status check, ~1-2 us a call; `python_call_overhead_us` is a cheap FMI call for
   scale): mean us per Co-Simulation doStep of 1 ms with the root held still (no flow) and, for
   feathers, over one period of the paper's stroke from rest (root motion set before each step
   at its midpoint); and mean us per Model Exchange derivative evaluation
   (setContinuousStates + getContinuousStateDerivatives). Each figure is the median of 3
   (--quick) or 5 repeated runs/blocks, to shed bursts of interference on a shared machine.
3. The chordwise and plain feathers under the stroke for 6 periods of 1.5 s (--quick: 2), side
   by side in one process: (a) the CS FMU stepped at 1 ms from Python, (b) the ME FMU through
   fmpy.simulate_fmu (CVode, root motion sampled at 1 ms; fmpy sets inputs only at output points,
   its CVode right-hand side does not re-apply them, so they are held at each 1 ms interval's
   start value: half a step behind the CS's midpoint hold, which shows in the plain feather's
   pointwise error),
   (c) direct CasADi `integrate()` (CVODES) with the stroke written symbolically into the ODE.
   All at rtol 1e-6 (atol 1e-8, as the CS shell derives from rtol). Wall times, ratios to (c)
   and the thrust ratio TR over the last half of the run. The chordwise flaps are chaotic, so
   (a)-(c) agree only statistically: compare TRs, not samples. The plain feather is periodic:
   the max pointwise thrust difference of (a) and (b) from (c) is reported too.

The machine this runs on may be shared and noisy: compare times within one run (the ratios),
not across runs. Writes <out>/fmu_models.json and <out>/fmu_models.png.

    python bench/fmu_models.py [--quick] [--models feather-plain,servo] [--out DIR]
    (full: several minutes; --quick: about a minute)
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from ctypes import POINTER, c_double
from pathlib import Path
from typing import Any, Iterator, Sequence

import casadi as ca
import fmpy
import matplotlib
import numpy as np
from featherstar.cosim.swimmer.metrics import thrust_metrics
from featherstar.cosim.swimmer.stroke import Stroke, root_motion, root_motion_symbolic
from featherstar.fmu_src.catalog import MODELS
from featherstar.fmu_src.export import build_fmu
from featherstar.fmu_src.integrate import integrate
from featherstar.fmu_src.model import Model
from fmpy import read_model_description
from fmpy.fmi3 import FMU3Model, FMU3Slave

RESULTS = Path(__file__).resolve().parent / "results"
QUICK_COLD = ("servo", "robot", "feather-plain")
STROKE_MODELS = ("feather-chordwise", "feather-plain")   # section 3, in this order
PERIODIC = ("feather-plain",)                            # pointwise comparison makes sense
STEP_S = 1e-3
RTOL = 1e-6
ATOL = 1e-8          # the CS shell uses atol = 1e-2 * rtol
STROKE_INPUTS = ("root_angle_rad", "root_rate_rad_s", "root_accel_rad_s2", "flow_speed_m_s")


def is_feather(name: str) -> bool:
    return name.startswith("feather-")


# --------------------------------------------------------------------------- helpers

@contextlib.contextmanager
def env_var(name: str, value: str | None) -> Iterator[None]:
    old = os.environ.get(name)
    if value is None:
        os.environ.pop(name, None)
    else:
        os.environ[name] = value
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = old


class Fmu:
    """A built FMU, extracted once, with its description and value references."""

    def __init__(self, path: Path, model: Model, extract_root: Path) -> None:
        self.path = path
        self.model = model
        self.description = read_model_description(str(path))
        self.unzipped = fmpy.extract(str(path), str(extract_root / path.stem))
        self.vr = {v.name: v.valueReference for v in self.description.modelVariables}

    def slave(self, name: str = "bench-cs") -> FMU3Slave:
        d = self.description
        fmu = FMU3Slave(guid=d.guid, unzipDirectory=self.unzipped,
                        modelIdentifier=d.coSimulation.modelIdentifier, instanceName=name)
        fmu.instantiate()
        return fmu

    def me(self, name: str = "bench-me") -> FMU3Model:
        d = self.description
        fmu = FMU3Model(guid=d.guid, unzipDirectory=self.unzipped,
                        modelIdentifier=d.modelExchange.modelIdentifier, instanceName=name)
        fmu.instantiate()
        return fmu

    def input_vrs(self) -> list[int]:
        return [self.vr[v.name] for v in self.model.inputs]


def stroke_inputs(stroke: Stroke, t: float) -> list[float]:
    return [*root_motion(stroke, t), 0.0]


def release(fmu: FMU3Slave | FMU3Model) -> None:
    fmu.terminate()
    fmu.freeInstance()


# --------------------------------------------------------------------------- 1. build time

def build_times(names: Sequence[str], cold: Sequence[str], cache: Path) -> tuple[dict, dict[str, Path]]:
    """Per model: construction, cold and cached build seconds; and the FMU paths (in `cache`)."""
    out: dict[str, dict[str, Any]] = {}
    paths: dict[str, Path] = {}
    for name in names:
        t0 = time.perf_counter()
        model = MODELS[name]()
        entry: dict[str, Any] = {"model_construction_s": time.perf_counter() - t0,
                                 "states": int(model.x.numel())}
        if name in cold:
            with env_var("FEATHERSTAR_CACHE", str(cache)):
                t0 = time.perf_counter()
                path = build_fmu(model, force=True)
                entry["cold_s"] = time.perf_counter() - t0
        else:
            entry["cold_s"] = None
            entry["cold_skipped"] = "--quick: taken from the user's cache instead"
            t0 = time.perf_counter()
            user = build_fmu(model)          # the user's cache (built there if missing)
            entry["fetch_from_user_cache_s"] = time.perf_counter() - t0
            target = cache / user.parent.name
            target.mkdir(parents=True, exist_ok=True)
            shutil.copy2(user, target / user.name)
        with env_var("FEATHERSTAR_CACHE", str(cache)):
            t0 = time.perf_counter()
            path = build_fmu(model)
            entry["cached_s"] = time.perf_counter() - t0
        entry["fmu_bytes"] = path.stat().st_size
        out[name] = entry
        paths[name] = path
        cold_text = f"{entry['cold_s']:.2f} s" if entry["cold_s"] is not None else "(skipped)"
        print(f"  built {name}: cold {cold_text}, cached {1e3 * entry['cached_s']:.1f} ms", flush=True)
    return out, paths


# --------------------------------------------------------------------------- 2. per-step cost

def cs_step_cost(fmu: Fmu, n_steps: int, stroke: Stroke | None, repeats: int) -> dict[str, Any]:
    """us per doStep(1 ms) (only the doStep call timed) and per loop iteration (with setFloat64).

    The run of `n_steps` from a fresh instance is repeated `repeats` times (identical work each
    time); the headline figure is the median over repeats, which sheds bursts of interference.
    """
    per_step, per_iteration = [], []
    inputs = fmu.input_vrs()
    for _ in range(repeats):
        slave = fmu.slave()
        slave.enterInitializationMode(tolerance=RTOL, startTime=0.0)
        if stroke is not None:
            slave.setFloat64(inputs, stroke_inputs(stroke, 0.0))
        slave.exitInitializationMode()
        in_step = 0.0
        loop0 = time.perf_counter()
        for k in range(n_steps):
            if stroke is not None:
                slave.setFloat64(inputs, stroke_inputs(stroke, (k + 0.5) * STEP_S))
            t0 = time.perf_counter()
            slave.doStep(k * STEP_S, STEP_S)
            in_step += time.perf_counter() - t0
        loop = time.perf_counter() - loop0
        release(slave)
        per_step.append(1e6 * in_step / n_steps)
        per_iteration.append(1e6 * loop / n_steps)
    return {"do_step_us": float(np.median(per_step)), "loop_iteration_us": float(np.median(per_iteration)),
            "do_step_us_per_repeat": per_step, "steps": n_steps, "repeats": repeats}


def me_derivative_cost(fmu: Fmu, n_evals: int, stroke: Stroke | None, blocks: int) -> dict[str, Any]:
    """Mean us per setContinuousStates + getContinuousStateDerivatives; and per bare
    getContinuousStates (a cheap FMI call: the Python/ctypes overhead for scale)."""
    me = fmu.me()
    me.enterInitializationMode(tolerance=RTOL, startTime=0.0)
    if stroke is not None:   # mid-upstroke: root moving and accelerating
        me.setFloat64(fmu.input_vrs(), stroke_inputs(stroke, 0.3 * stroke.t_up_s))
    me.exitInitializationMode()
    me.updateDiscreteStates()
    me.enterContinuousTimeMode()
    nx = fmu.description.numberOfContinuousStates
    x = np.zeros(nx)
    dx = np.zeros(nx)
    px, pdx = x.ctypes.data_as(POINTER(c_double)), dx.ctypes.data_as(POINTER(c_double))
    me.getContinuousStates(px, nx)
    x += 1e-3 * np.sin(np.arange(nx) + 1.0)       # off the rest state
    evals, calls = [], []
    for _ in range(blocks):   # median over blocks sheds bursts of interference
        t0 = time.perf_counter()
        for _ in range(n_evals):
            me.setContinuousStates(px, nx)
            me.getContinuousStateDerivatives(pdx, nx)
        evals.append(1e6 * (time.perf_counter() - t0) / n_evals)
        t0 = time.perf_counter()
        for _ in range(n_evals):
            me.getContinuousStates(pdx, nx)
        calls.append(1e6 * (time.perf_counter() - t0) / n_evals)
    release(me)
    return {"derivative_us": float(np.median(evals)), "python_call_overhead_us": float(np.median(calls)),
            "derivative_us_per_block": evals, "evaluations_per_block": n_evals, "blocks": blocks}


def step_costs(fmus: dict[str, Fmu], quick: bool, stroke: Stroke) -> dict[str, dict]:
    rest_steps = 300 if quick else 1000
    stroke_steps = int(round(stroke.period_s / STEP_S))     # one whole period from rest
    repeats = 3 if quick else 5
    n_evals = 500 if quick else 2000
    out = {}
    for name, fmu in fmus.items():
        entry: dict[str, Any] = {"cs_rest": cs_step_cost(fmu, rest_steps, None, repeats)}
        if is_feather(name):
            entry["cs_stroke"] = cs_step_cost(fmu, stroke_steps, stroke, repeats)
        entry["me"] = me_derivative_cost(fmu, n_evals, stroke if is_feather(name) else None, repeats)
        out[name] = entry
        stroke_text = (f", stroke {entry['cs_stroke']['do_step_us']:.0f} us" if "cs_stroke" in entry else "")
        print(f"  step cost {name}: CS rest {entry['cs_rest']['do_step_us']:.0f} us{stroke_text}, "
              f"ME derivative {entry['me']['derivative_us']:.1f} us", flush=True)
    return out


# --------------------------------------------------------------------------- 3. stroke runs

def run_cs(fmu: Fmu, stroke: Stroke, grid: np.ndarray) -> np.ndarray:
    """(a) thrust on `grid` from the CS FMU stepped at 1 ms, root motion at each step's midpoint."""
    slave = fmu.slave("stroke-cs")
    inputs, thrust_vr = fmu.input_vrs(), [fmu.vr["thrust_N"]]
    slave.enterInitializationMode(tolerance=RTOL, startTime=0.0)
    slave.setFloat64(inputs, stroke_inputs(stroke, 0.0))
    slave.exitInitializationMode()
    thrust = np.empty(len(grid))
    thrust[0] = slave.getFloat64(thrust_vr)[0]
    for k in range(len(grid) - 1):
        slave.setFloat64(inputs, stroke_inputs(stroke, (k + 0.5) * STEP_S))
        slave.doStep(k * STEP_S, STEP_S)
        thrust[k + 1] = slave.getFloat64(thrust_vr)[0]
    release(slave)
    return thrust


def run_me(fmu: Fmu, stroke: Stroke, grid: np.ndarray) -> np.ndarray:
    """(b) thrust on `grid` from fmpy.simulate_fmu on the ME FMU (CVode), inputs sampled at 1 ms."""
    signals = np.array([(t, *stroke_inputs(stroke, t)) for t in grid],
                       dtype=[("time", np.float64)] + [(n, np.float64) for n in STROKE_INPUTS])
    result = fmpy.simulate_fmu(fmu.unzipped, model_description=fmu.description, fmi_type="ModelExchange",
                               start_time=0.0, stop_time=float(grid[-1]), relative_tolerance=RTOL,
                               output_interval=STEP_S, input=signals, output=["thrust_N"],
                               record_events=False)
    return np.interp(grid, result["time"], result["thrust_N"])


def run_casadi(model: Model, stroke: Stroke, grid: np.ndarray) -> np.ndarray:
    """(c) thrust on `grid` from direct CVODES integration with the stroke inside the ODE."""
    def drive(t: ca.SX) -> ca.SX:
        angle, rate, accel = root_motion_symbolic(t, stroke.t_up_s, stroke.t_hold_up_s, stroke.t_down_s,
                                                  stroke.t_hold_down_s, stroke.amplitude_rad)
        return ca.vertcat(angle, rate, accel, 0.0)

    _, outputs = integrate(model, grid, drive, rtol=RTOL, atol=ATOL)
    return outputs[:, [v.name for v in model.outputs].index("thrust_N")]


def stroke_run(name: str, fmu: Fmu, stroke: Stroke, periods: int) -> tuple[dict, dict[str, np.ndarray]]:
    n = int(round(periods * stroke.period_s / STEP_S))
    grid = STEP_S * np.arange(n + 1)
    runners = {
        "cs_fmu": lambda: run_cs(fmu, stroke, grid),
        "me_fmu": lambda: run_me(fmu, stroke, grid),
        "casadi": lambda: run_casadi(fmu.model, stroke, grid),
    }
    thrust: dict[str, np.ndarray] = {}
    wall: dict[str, float] = {}
    for key, runner in runners.items():
        t0 = time.perf_counter()
        thrust[key] = runner()
        wall[key] = time.perf_counter() - t0
        print(f"  {name} {key}: {wall[key]:.2f} s", flush=True)
    settle = periods - periods // 2                   # last half, in whole periods
    a, b = settle * stroke.period_s, float(grid[-1])
    entry: dict[str, Any] = {"periods": periods, "samples": len(grid), "window_s": [a, b]}
    scale = float(np.max(np.abs(thrust["casadi"])))
    for key in runners:
        metrics = thrust_metrics(grid, thrust[key], a, b, stroke.period_s, periods // 2)
        run = {"wall_s": wall[key], "wall_ratio_to_casadi": wall[key] / wall["casadi"],
               "thrust_ratio": metrics["thrust_ratio"], "mean_thrust_N": metrics["mean_thrust_N"],
               "per_period_thrust_ratio": metrics.get("per_period_thrust_ratio", [])}
        if name in PERIODIC and key != "casadi":
            diff = np.abs(thrust[key] - thrust["casadi"])
            run["max_abs_thrust_diff_vs_casadi_N"] = float(diff.max())
            run["max_abs_thrust_diff_last_half_N"] = float(diff[grid >= a - 1e-12].max())
            run["max_abs_thrust_casadi_N"] = scale
        entry[key] = run
    return entry, thrust


# --------------------------------------------------------------------------- report

def print_table(result: dict) -> None:
    print("\nBuild time (s)            cold     cached")
    for name, e in result["build"].items():
        cold = f"{e['cold_s']:8.2f}" if e["cold_s"] is not None else "       -"
        print(f"  {name:20s} {cold}   {e['cached_s']:8.4f}")
    print("\nFMU cost from Python (us)  CS step rest  CS step stroke  ME derivative  (call overhead)")
    for name, e in result["step_cost"].items():
        stroke = f"{e['cs_stroke']['do_step_us']:14.0f}" if "cs_stroke" in e else "             -"
        print(f"  {name:20s} {e['cs_rest']['do_step_us']:12.0f}  {stroke}  {e['me']['derivative_us']:13.1f}"
              f"  ({e['me']['python_call_overhead_us']:.1f})")
    for name, e in result["stroke_runs"].items():
        print(f"\n{name}, {e['periods']} periods of the stroke; TR over t in [{e['window_s'][0]:g}, {e['window_s'][1]:g}] s")
        print("  run        wall (s)  ratio to casadi     TR   mean thrust (mN)  max |dT| vs casadi (mN)")
        for key in ("cs_fmu", "me_fmu", "casadi"):
            r = e[key]
            diff = (f"{1e3 * r['max_abs_thrust_diff_vs_casadi_N']:10.3f} (|T| max {1e3 * r['max_abs_thrust_casadi_N']:.2f})"
                    if "max_abs_thrust_diff_vs_casadi_N" in r else "         -")
            print(f"  {key:8s} {r['wall_s']:9.2f}  {r['wall_ratio_to_casadi']:15.2f}  {r['thrust_ratio']:5.2f}"
                  f"  {1e3 * r['mean_thrust_N']:16.3f}  {diff}")


def plot(result: dict, path: Path) -> None:
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from featherstar.cosim.plotstyle import save_figure
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    ax = axes[0]
    names = list(result["build"])
    x = np.arange(len(names))
    cold = [e["cold_s"] if e["cold_s"] is not None else np.nan for e in result["build"].values()]
    ax.bar(x - 0.2, cold, 0.4, label="cold")
    ax.bar(x + 0.2, [e["cached_s"] for e in result["build"].values()], 0.4, label="cached")
    ax.set_yscale("log")
    ax.set_xticks(x, names, rotation=30, ha="right")
    ax.set_xlabel("FMU")
    ax.set_ylabel("build time (s)")
    ax.set_title("FMU build")
    ax.legend()

    ax = axes[1]
    names = list(result["step_cost"])
    x = np.arange(len(names))
    sc = result["step_cost"]
    ax.bar(x - 0.27, [sc[n]["cs_rest"]["do_step_us"] for n in names], 0.27, label="CS doStep 1 ms, rest")
    ax.bar(x, [sc[n]["cs_stroke"]["do_step_us"] if "cs_stroke" in sc[n] else np.nan for n in names], 0.27,
           label="CS doStep 1 ms, stroke")
    ax.bar(x + 0.27, [sc[n]["me"]["derivative_us"] for n in names], 0.27, label="ME derivative")
    ax.set_yscale("log")
    ax.set_xticks(x, names, rotation=30, ha="right")
    ax.set_xlabel("FMU")
    ax.set_ylabel("µs per call (from Python)")
    ax.set_title("FMU cost per call")
    ax.legend(fontsize=8)

    ax = axes[2]
    runs = result["stroke_runs"]
    names = list(runs)
    x = np.arange(len(names))
    for i, (key, label) in enumerate((("cs_fmu", "CS FMU, 1 ms"), ("me_fmu", "ME FMU, simulate_fmu"),
                                      ("casadi", "CasADi integrate"))):
        bars = ax.bar(x + (i - 1) * 0.27, [runs[n][key]["wall_s"] for n in names], 0.27, label=label)
        ax.bar_label(bars, [f"TR {runs[n][key]['thrust_ratio']:.2f}" for n in names], fontsize=7)
    ax.set_xticks(x, [f"{n}\n{runs[n]['periods']} periods" for n in names])
    ax.set_xlabel("FMU and its run length")
    ax.set_yscale("log")
    ax.set_ylabel("wall time (s)")
    ax.set_title("stroke run (label: TR over last half)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------- main

def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true",
                        help="cold-build only servo, robot, feather-plain; 2 stroke periods; fewer steps")
    parser.add_argument("--models", default=",".join(MODELS),
                        help=f"comma-separated subset of {', '.join(MODELS)} (default: all)")
    parser.add_argument("--periods", type=int, default=None,
                        help="stroke periods in section 3 (default 6, --quick 2)")
    parser.add_argument("--out", type=Path, default=RESULTS, help="output folder (default bench/results)")
    args = parser.parse_args(argv)
    args.models = [m.strip() for m in args.models.split(",") if m.strip()]
    unknown = [m for m in args.models if m not in MODELS]
    if unknown or not args.models:
        parser.error(f"unknown model(s) {unknown}; known: {', '.join(MODELS)}")
    if args.periods is None:
        args.periods = 2 if args.quick else 6
    if args.periods < 2:
        parser.error("--periods must be >= 2 (TR is taken over the last half)")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    stroke = Stroke()
    names = [n for n in MODELS if n in args.models]
    cold = [n for n in names if not args.quick or n in QUICK_COLD]
    result: dict[str, Any] = {
        "settings": {"quick": args.quick, "models": names, "cold_built": cold, "stroke_periods": args.periods,
                     "stroke_period_s": stroke.period_s, "communication_step_s": STEP_S, "rtol": RTOL,
                     "atol": ATOL},
        "machine": {"cpus": os.cpu_count(), "load_avg_1min_at_start": os.getloadavg()[0],
                    "python": platform.python_version(), "fmpy": fmpy.__version__, "casadi": ca.__version__},
        "notes": [
            "All FMU figures are measured from Python through fmpy: each includes fmpy's ctypes call and "
            "status check (python_call_overhead_us is the mean cost of a cheap FMI call).",
            "Times come from one run on a possibly shared machine: compare within the run (ratios).",
            "CS: root motion held over each 1 ms step at its midpoint value; thrust read after the step. "
            "ME: fmpy.simulate_fmu, CVode, root motion sampled at 1 ms; fmpy sets inputs only at output "
            "points (not inside its CVode right-hand side), so they are held at each interval's start "
            "value, half a step behind the CS midpoint hold. CasADi: CVODES with the stroke symbolic in "
            "the ODE. TR over the last half of the run (whole periods).",
            "The chordwise feather is chaotic: its runs agree only statistically (compare TRs).",
        ],
    }
    wall0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="featherstar-bench-") as tmp:
        tmp = Path(tmp)
        print("1. build time", flush=True)
        result["build"], paths = build_times(names, cold, tmp / "cache")
        fmus = {n: Fmu(paths[n], MODELS[n](), tmp / "extracted") for n in names}
        print("2. per-step FMU cost (from Python)", flush=True)
        result["step_cost"] = step_costs(fmus, args.quick, stroke)
        print(f"3. stroke runs, {args.periods} periods", flush=True)
        result["stroke_runs"] = {}
        for name in STROKE_MODELS:
            if name in fmus:
                result["stroke_runs"][name], _ = stroke_run(name, fmus[name], stroke, args.periods)
    result["machine"]["load_avg_1min_at_end"] = os.getloadavg()[0]
    result["total_wall_s"] = time.perf_counter() - wall0
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "fmu_models.json").write_text(json.dumps(result, indent=2, allow_nan=True) + "\n")
    plot(result, args.out / "fmu_models.png")
    print_table(result)
    print(f"\nwrote {args.out / 'fmu_models.json'} and .png ({result['total_wall_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
