"""featherstar against other co-simulation masters, on the same systems of the same FMUs.

Systems (the peers have no stroke block: the stroke comes from a bench-local FMU that carries its
own clock, bench/_stroke_fmu.py; the servo and feathers are featherstar's FMI 2.0 FMUs, what
`featherstar build --fmi 2` writes, because FMI 2.0 is what every peer reads):
  plain    stroke -> plain feather (the `kinematic` scene with a plain feather: periodic, not
           chaotic, so the recorded thrust can be compared sample by sample)
  testbed  stroke controller -> servo <-> chordwise feather, WR 7.5 (the shipped `testbed` scene;
           the flaps are chaotic: compare TR and mean thrust, the samples part after a while)

Runs on each system, all recording the feather's thrust every 1 ms:
  featherstar strong              the shipped scene as users run it (stroke block, CasADi models
                                  in one ODE, CVODE Adams, rtol 1e-6)
  featherstar strong, FMU files   the peers' very FMU files as Model Exchange, one ODE
  featherstar mixed               the stroke FMU stepped (Co-Simulation), servo and feather one ODE
  featherstar jacobi / gauss-seidel   every FMU stepped at 1 ms
  libcosim (libcosimpy), Ecos (ecospy)   their fixed-step masters at 1 ms
  fmpy simulate_fmu (Co-Simulation)      where a system is one FMU: the plain feather with the
                                  root motion as an input table (fmpy runs no coupled systems)
Every FMU integrates inside at rtol 1e-6 (the CS shell's default, and featherstar's master.rtol).
Reference: featherstar strong on the shipped scene at rtol 1e-10, atol 1e-12. Accuracy: relative
error of TR and mean thrust over the scene's metric window, and the largest thrust difference
over the whole run relative to the reference's peak thrust. Wall time: each run end to end
(loading the FMUs included), best of --repeats taken in rounds, as a ratio to featherstar strong in
the same run.
A peer that does not import is skipped with the import error; a run that fails is reported
failed with its error, never left out.

    python bench/peers.py [--quick] [--systems plain,testbed] [--repeats N] [--out DIR]
A full run also runs every catalog FMU, FMI 3.0 and 2.0, alone in each master (bench/_fmu_compat.py).
Writes <out>/peers.json and <out>/peers.png (error against wall time, log-log) and prints the
README's comparison table (markdown, from the JSON).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass
from importlib import metadata, resources
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the bench-local helpers (not a package)

from _fmu_compat import compat_matrix  # noqa: E402
from _peer_masters import RUNNERS, FmuSystem, available  # noqa: E402
from _stroke_fmu import build_stroke_fmu  # noqa: E402
from featherstar.cosim.scene.data import Scene, scene_from_dict  # noqa: E402
from featherstar.cosim.swimmer.metrics import thrust_metrics  # noqa: E402
from featherstar.cosim.swimmer.run import run_scene  # noqa: E402
from featherstar.cosim.swimmer.stroke import Stroke, root_motion  # noqa: E402
from featherstar.fmu_src.catalog import build_model  # noqa: E402
from featherstar.fmu_src.export import build_fmu  # noqa: E402
from _peers_report import markdown_table, plot  # noqa: E402

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"
STEP_S = 1e-3
RTOL = 1e-6            # every run's integrator tolerance (FMU shells and featherstar's master)
REF_RTOL, REF_ATOL = 1e-10, 1e-12
THRUST = "feather.thrust_N"
NOTES = [
    "The peers have no stroke block: the stroke is bench/_stroke_fmu.py's FMU (a clock state and the "
    "root motion of featherstar.cosim.swimmer.stroke at it), exact at every communication point. The "
    "reference and 'featherstar strong' use the shipped scene's stroke block instead, an independent "
    "check of that FMU; 'featherstar strong, FMU files' runs the peers' very FMU files as Model Exchange.",
    "Every peer reads FMI 2.0: servo and feather are featherstar's FMI 2.0 builds (featherstar build --fmi 2); "
    "their Co-Simulation shell integrates at rtol 1e-6 when the importer defines no tolerance "
    "(libcosim and Ecos do not), the same as featherstar's master.rtol here.",
    "libcosim and fmpy record an output after a step before the next inputs are set (libcosim's time "
    "series of feather.root_angle_rad at t = h is the stroke at 0), Ecos and featherstar after: the "
    "feathers' thrust feeds through from the root motion (added mass), so the two conventions' records "
    "differ in that part while their TR and mean thrust agree (nearest_records).",
    "The chordwise flaps are chaotic: over a whole run, two accurate solutions part, so TR and mean "
    "thrust errors below ~1e-6 and the whole-run max |dT| measure the chaos as much as the method; "
    "first_period_thrust_error_rel_peak (the first stroke period, before they part) does not.",
    "Wall times are end to end (FMU loading, and featherstar's plan, included) on a shared 2-core machine: "
    "compare the ratios within one run. CPU times are the process's over the same span (every thread; "
    "libcosim may step its slaves on worker threads), less sensitive to the machine's other users.",
]
STRONG = "featherstar strong"


@dataclass(frozen=True)
class System:
    """One benchmark system: the shipped scene it comes from and the feather's build options."""

    name: str
    description: str
    scene: str
    feather_options: dict
    servo: bool
    periods: int           # full run; the metric window is the last half, in whole periods

    def connections(self) -> tuple[tuple[str, str], ...]:
        root = ("angle_rad", "rate_rad_s", "accel_rad_s2")
        if not self.servo:
            return tuple((f"stroke.{p}", f"feather.root_{p}") for p in root)
        return (("stroke.angle_rad", "servo.setpoint_rad"), ("feather.root_torque_Nm", "servo.load_torque_Nm"),
                *((f"servo.{p}", f"feather.root_{p}") for p in root))


SYSTEMS = {
    "plain": System("plain", "stroke -> plain feather (periodic)", "kinematic", {"morphology": "plain"}, False, 6),
    "testbed": System("testbed", "stroke -> servo <-> chordwise feather WR 7.5 (chaotic flaps)", "testbed",
                      {"morphology": "chordwise", "n_units": 10}, True, 6),
}


def shipped_scene_data(system: System) -> dict:
    """The shipped scene's TOML as a dict, its feather rebuilt with the system's options."""
    text = (resources.files("featherstar.cosim.scenes") / f"{system.scene}.toml").read_text(encoding="utf-8")
    data = tomllib.loads(text)
    data["blocks"]["feather"]["options"] = dict(system.feather_options)
    return data


def scene_stroke(system: System) -> Stroke:
    """The shipped scene's stroke controller, which the stroke FMU then reproduces."""
    controller = shipped_scene_data(system)["blocks"]["controller"]
    return Stroke(**{f.name: float(controller[f.name]) for f in dataclasses.fields(Stroke) if f.name in controller})


def feather_parameters(system: System, stroke: Stroke) -> dict[str, float]:
    """What featherstar sets on the feather in the shipped scene, for the peers to set too: the
    scene's parameters that this morphology has, and the stroke amplitude the stroke block shares."""
    names = {p.name for p in build_model("feather", system.feather_options).parameters}
    scene = shipped_scene_data(system)["blocks"]["feather"].get("parameters", {})
    values = {k: float(v) for k, v in scene.items() if k in names}
    values["stroke_amplitude_rad"] = stroke.amplitude_rad
    return values


def build_fmus(system: System, stroke: Stroke, folder: Path) -> dict[str, Path]:
    """FMI 2.0 FMUs of the system by instance name (built once, then from featherstar's cache)."""
    fmus = {"stroke": build_stroke_fmu(stroke, folder / "stroke")}
    if system.servo:
        fmus["servo"] = build_fmu(build_model("servo"), folder / "servo", fmi_version=2)
    fmus["feather"] = build_fmu(build_model("feather", system.feather_options), folder / "feather", fmi_version=2)
    return fmus


def fmu_scene(system: System, fmus: dict[str, Path], start_values: dict[str, float], stroke_interface: str) -> Scene:
    """The peers' system as a featherstar scene: the same FMU files, connections and start values."""
    data = shipped_scene_data(system)
    blocks: dict[str, Any] = {name: {"kind": "fmu", "fmu": str(path)} for name, path in fmus.items()}
    blocks["stroke"]["interface"] = stroke_interface
    blocks["feather"]["parameters"] = {k.split(".", 1)[1]: v for k, v in start_values.items()}
    blocks["tank"] = data["blocks"]["tank"]
    metrics = dict(data["metrics"], angle="servo.angle_rad" if system.servo else "stroke.angle_rad")
    connections = [f"{a} -> {b}" for a, b in system.connections()] + ["tank.flow_speed_m_s -> feather.flow_speed_m_s"]
    return scene_from_dict({"connections": connections, "master": data["master"], "metrics": metrics,
                            "blocks": blocks}, name=f"peers-{system.name}")


def timed_rounds(runs: dict[str, Callable[[], np.ndarray]], repeats: int, n_samples: int
                 ) -> dict[str, tuple[np.ndarray, list[float], list[float]] | str]:
    """Each run `repeats` times, in rounds (every run once, then again): a burst of load on this
    shared machine then slows one round of every run, not every repeat of one. Per run: the first
    round's record, every wall time and every CPU time (the process's, all its threads: less
    sensitive to other users of the machine), or the error that stopped it (a failure is a result)."""
    out: dict[str, tuple[np.ndarray, list[float], list[float]] | str] = {}
    for _ in range(repeats):
        for label, run in runs.items():
            if isinstance(out.get(label), str):
                continue
            try:
                t0, c0 = time.perf_counter(), time.process_time()
                values = np.asarray(run(), dtype=float)
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                if values.shape != (n_samples,) or not np.all(np.isfinite(values)):
                    raise RuntimeError(f"recorded {values.size} thrust samples, {int(np.sum(~np.isfinite(values)))} "
                                       f"not finite; expected {n_samples} finite")
            except Exception as exc:  # a peer's failure is reported, and the bench goes on
                out[label] = f"{type(exc).__name__}: {exc}"
                continue
            record, walls, cpus = out.get(label, (values, [], []))
            out[label] = (record, [*walls, wall], [*cpus, cpu])
    return out


def featherstar_runs(system: System, fmus: dict[str, Path], start: dict[str, float], short: dict[str, float],
                     stroke: Stroke) -> list[tuple[str, str, Callable[[], np.ndarray]]]:
    """(label, coupling, run) of every featherstar run; each run returns the thrust on the grid."""
    shipped = scene_from_dict(shipped_scene_data(system), name=system.scene)
    as_me, as_cs = fmu_scene(system, fmus, start, "me"), fmu_scene(system, fmus, start, "cs")
    # A stroke FMU gives the plan no period: the same run length and metric period, stated.
    timed = {"master.t_end_s": short["master.periods"] * stroke.period_s, "metrics.period_s": stroke.period_s}

    def run(scene: Scene, coupling: str, extra: dict[str, float]) -> Callable[[], np.ndarray]:
        overrides = {**short, **extra, "master.coupling": coupling, "master.rtol": RTOL, "master.atol": 1e-2 * RTOL}
        return lambda: run_scene(scene, overrides, outputs=[THRUST])[THRUST]

    return [(STRONG, "strong", run(shipped, "strong", {})),
            ("featherstar strong, FMU files", "strong", run(as_me, "strong", timed)),
            ("featherstar mixed", "mixed", run(as_cs, "mixed", timed)),
            ("featherstar jacobi", "jacobi", run(as_cs, "jacobi", timed)),
            ("featherstar gauss-seidel", "gauss-seidel", run(as_cs, "gauss-seidel", timed))]


def peer_runs(system: System, fmus: dict[str, Path], start: dict[str, float], stroke: Stroke,
              stop_s: float) -> list[tuple[str, str, Callable[[], np.ndarray] | str]]:
    """(label, coupling, run or the reason it cannot run) of every peer on the system."""
    reasons = available()
    coupled = FmuSystem(dict(fmus), system.connections(), dict(start), STEP_S, stop_s)
    out: list[tuple[str, str, Callable[[], np.ndarray] | str]] = []
    for peer, label in (("libcosim", "libcosim (libcosimpy)"), ("ecos", "Ecos (ecospy)")):
        out.append((label, "fixed-step co-simulation",
                    reasons[peer] or (lambda runner=RUNNERS[peer]: runner(coupled, THRUST))))
    label = "fmpy simulate_fmu (CS)"
    if reasons["fmpy"]:
        out.append((label, "co-simulation, one FMU", reasons["fmpy"]))
    elif system.servo:
        out.append((label, "co-simulation, one FMU", "fmpy.simulate_fmu runs one FMU; the test bed's servo and "
                    "feather drive each other (a loop no input table can stand for)"))
    else:
        alone = FmuSystem({"feather": fmus["feather"]}, (), start, STEP_S, stop_s)

        def inputs(grid: np.ndarray) -> dict[str, np.ndarray]:
            motion = np.array([root_motion(stroke, t) for t in grid])
            signals = {f"root_{p}": motion[:, i] for i, p in enumerate(("angle_rad", "rate_rad_s", "accel_rad_s2"))}
            return {**signals, "flow_speed_m_s": np.zeros(len(grid))}   # still water, as everywhere

        out.append((label, "co-simulation, one FMU (root motion as an input table)",
                    lambda: RUNNERS["fmpy"](alone, THRUST, inputs, RTOL)))
    return out


def relative(value: float, reference: float) -> float:
    return abs(value / reference - 1.0) if reference else math.inf


def measure_system(system: System, periods: int, repeats: int, folder: Path, log: Callable[[str], None] = print) -> dict:
    """Every run on one system against the tight reference; rows with errors and wall-time ratios."""
    stroke = scene_stroke(system)
    settle = periods - periods // 2
    short = {"master.periods": periods, "metrics.settle_periods": settle, "master.step_s": STEP_S}
    fmus = build_fmus(system, stroke, folder / system.name)
    start = {f"feather.{k}": v for k, v in feather_parameters(system, stroke).items()}
    stop_s = periods * stroke.period_s
    grid = STEP_S * np.arange(int(round(stop_s / STEP_S)) + 1)
    a, b = settle * stroke.period_s, stop_s

    t0 = time.perf_counter()
    ref_overrides = {**short, "master.coupling": "strong", "master.rtol": REF_RTOL, "master.atol": REF_ATOL}
    reference = run_scene(scene_from_dict(shipped_scene_data(system), name=system.scene), ref_overrides,
                          outputs=[THRUST])[THRUST]
    ref_wall = time.perf_counter() - t0
    ref = thrust_metrics(grid, reference, a, b, stroke.period_s, periods // 2)
    peak = float(np.max(np.abs(reference)))
    first = grid <= stroke.period_s + 1e-12   # before the chaotic flaps let accurate runs part
    log(f"{system.name}: reference (strong, rtol {REF_RTOL:g}) TR {ref['thrust_ratio']:.6f}, "
        f"mean thrust {1e3 * ref['mean_thrust_N']:.4f} mN, {ref_wall:.1f} s")

    rows: list[dict[str, Any]] = []
    traces: dict[str, np.ndarray] = {}
    plan = [*featherstar_runs(system, fmus, start, short, stroke), *peer_runs(system, fmus, start, stroke, stop_s)]
    measured = timed_rounds({label: run for label, _, run in plan if not isinstance(run, str)}, repeats, grid.size)
    for label, coupling, run in plan:
        row: dict[str, Any] = {"run": label, "coupling": coupling}
        outcome = run if isinstance(run, str) else measured[label]
        if isinstance(outcome, str):
            status = "skipped" if isinstance(run, str) else "failed"
            rows.append({**row, "status": status, "reason": outcome})
            log(f"  {label:32s} {status}: {outcome}")
            continue
        thrust, walls, cpus = outcome
        m = thrust_metrics(grid, thrust, a, b, stroke.period_s, periods // 2)
        row.update(status="ok", wall_s=min(walls), wall_s_each=walls, cpu_s=min(cpus), cpu_s_each=cpus,
                   thrust_ratio=m["thrust_ratio"],
                   mean_thrust_N=m["mean_thrust_N"], tr_rel_error=relative(m["thrust_ratio"], ref["thrust_ratio"]),
                   mean_thrust_rel_error=relative(m["mean_thrust_N"], ref["mean_thrust_N"]),
                   max_thrust_error_rel_peak=float(np.max(np.abs(thrust - reference))) / peak,
                   first_period_thrust_error_rel_peak=float(np.max(np.abs(thrust - reference)[first])) / peak)
        traces[label] = thrust
        rows.append(row)
        log(f"  {label:32s} TR error {row['tr_rel_error']:.2e}, mean thrust error {row['mean_thrust_rel_error']:.2e}, "
            f"max |dT|/peak {row['max_thrust_error_rel_peak']:.2e}, {row['wall_s']:.2f} s")
    strong = next((r for r in rows if r["run"] == STRONG and r["status"] == "ok"), None)
    for row in rows:
        if row["status"] == "ok" and strong is not None:
            row["wall_over_featherstar_strong"] = row["wall_s"] / strong["wall_s"]
            row["cpu_over_featherstar_strong"] = row["cpu_s"] / strong["cpu_s"]
    return {"description": system.description, "scene": system.scene, "feather_options": system.feather_options,
            "fmus": {k: v.name for k, v in fmus.items()}, "start_values": start, "periods": periods,
            "metric_window_s": [a, b], "reference": {"wall_s": ref_wall, "thrust_ratio": ref["thrust_ratio"],
                                                     "mean_thrust_N": ref["mean_thrust_N"], "peak_thrust_N": peak},
            "identical_records": identical_records(traces), "nearest_records": nearest_records(traces), "rows": rows}


def identical_records(traces: dict[str, np.ndarray]) -> list[list[str]]:
    """Groups of runs whose recorded thrust is bit-identical (same algorithm, same FMU calls)."""
    groups: list[list[str]] = []
    for label, values in traces.items():
        for group in groups:
            if np.array_equal(traces[group[0]], values):
                group.append(label)
                break
        else:
            groups.append([label])
    return [g for g in groups if len(g) > 1]


def nearest_records(traces: dict[str, np.ndarray]) -> dict[str, dict[str, Any]]:
    """For each run, the other run whose thrust record is nearest (largest difference, N): which
    masters compute the same thing, and which differ only in when they read an output."""
    out: dict[str, dict[str, Any]] = {}
    for label, values in traces.items():
        others = {k: float(np.max(np.abs(v - values))) for k, v in traces.items() if k != label}
        if others:
            nearest = min(others, key=others.get)
            out[label] = {"run": nearest, "max_abs_thrust_diff_N": others[nearest]}
    return out


def versions() -> dict[str, str | None]:
    out: dict[str, str | None] = {"python": platform.python_version()}
    for dist in ("featherstar", "fmpy", "casadi", "libcosimpy", "ecospy"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 periods per system, one repeat")
    parser.add_argument("--systems", default=",".join(SYSTEMS), help=f"comma-separated subset of {', '.join(SYSTEMS)}")
    parser.add_argument("--periods", type=int, help="stroke periods per run (default 6, --quick 2)")
    parser.add_argument("--repeats", type=int, help="runs per timing, best taken (default 3, --quick 1)")
    parser.add_argument("--out", type=Path, default=RESULTS, help="output folder (default docs/results)")
    args = parser.parse_args(argv)
    args.systems = [s.strip() for s in args.systems.split(",") if s.strip()]
    unknown = [s for s in args.systems if s not in SYSTEMS]
    if unknown or not args.systems:
        parser.error(f"--systems: unknown system(s) {unknown}; known: {', '.join(SYSTEMS)}")
    args.periods = args.periods if args.periods is not None else (2 if args.quick else None)
    if args.periods is not None and args.periods < 2:
        parser.error(f"--periods {args.periods}: must be >= 2 (the metrics take the last half)")
    args.repeats = args.repeats if args.repeats is not None else (1 if args.quick else 3)
    if args.repeats < 1:
        parser.error(f"--repeats {args.repeats}: must be >= 1")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    wall0 = time.perf_counter()
    result: dict[str, Any] = {
        "settings": {"quick": args.quick, "systems": args.systems, "repeats": args.repeats, "step_s": STEP_S,
                     "rtol": RTOL, "reference_rtol": REF_RTOL, "reference_atol": REF_ATOL},
        "machine": {"cpus": os.cpu_count(), "load_avg_1min_at_start": os.getloadavg()[0], **versions()},
        "peers_unavailable": {k: v for k, v in available().items() if v},
        "systems": {},
        "notes": NOTES,
    }
    with tempfile.TemporaryDirectory(prefix="featherstar-peers-") as folder:
        for name in args.systems:
            system = SYSTEMS[name]
            result["systems"][name] = measure_system(system, args.periods or system.periods, args.repeats, Path(folder))
        if args.quick:
            result["fmu_compatibility"] = "not run with --quick (a full run builds all ten FMUs)"
        else:
            print("every catalog FMU, FMI 3.0 and 2.0, alone in each master", flush=True)
            result["fmu_compatibility"] = compat_matrix(Path(folder) / "compat")
    result["machine"]["load_avg_1min_at_end"] = os.getloadavg()[0]
    result["total_wall_s"] = time.perf_counter() - wall0
    result["readme_table_md"] = markdown_table(result)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "peers.json").write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    plot(result, args.out / "peers.png")
    print("\n" + result["readme_table_md"])
    print(f"\nwrote {args.out / 'peers.json'} and .png ({result['total_wall_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
