"""The feather's speed with the O(N) chain solve, against the dense formulation it replaced.

In one run, on one machine (compare the ratios: a shared machine is noisy):
1. Compiled RHS cost per evaluation (bench/_rhs_cost.py: CasADi's C compiled as the FMU export
   compiles model code, called in a C loop): state derivatives only, and state derivatives plus
   outputs (what an FMU evaluates per call), for plain / chordwise / spanwise at N = 5, 10, 20, 40;
   and the formulation before the change (commit 32dc597: dense mass matrix, symbolic LDLᵀ) at
   N = 5, 10, taken from `git archive` of that commit into a temporary directory.
2. FMU builds: every shipped FMU cold, in a fresh cache, timed together; and one chordwise
   and one plain feather per N, each built by a child process under /usr/bin/time -v (wall time
   and peak RSS).
3. The chordwise kinematic scene (6 periods of 1.5 s, CVODES Adams, rtol 1e-6): the FMU master
   on today's FMU, the same equations composed monolithically and compiled
   (featherstar.dashboard.monolithic), today's master on the FMU built from commit 32dc597 (the model's
   share of the change), and commit 32dc597's own master on that FMU (the scene as it ran before
   the change: Python right-hand side, dense model; in a child process, timed inside it), in
   rotating order, `--repeats` times each, median wall times. TR of each; the old model's chaos band is the range
   of its TR at rtol 1e-6, 1e-7 and 1e-8 (the flapped feather is chaotic: TRs of accurate runs
   scatter, and a TR inside the band is as good as the old model's own), and today's model's band
   over the same tolerances beside it (the two agree if they converge to the same TR).
4. 6-period run time of the kinematic scene through the master against N (chordwise and plain).
5. Where the integrator's steps go: steps and RHS evaluations of the chordwise scene with one
   suspect relaxed at a time (flap-stop stiffness, smoothing and damping, bending stiffness, the
   sheet's material damping removed, BDF): probes of what limits the step, not changes to the
   model; and the short spanwise sweep geometry with and without the sheet's damping.

Writes docs/results/feather_speed.json and feather_speed.png.

    python bench/feather_speed.py [--quick] [--repeats 3] [--out DIR]
    (full: ~15 min on a quiet 2-core machine; --quick: N = 5, 10 only, one repeat)
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path
from typing import Any, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import casadi as ca  # noqa: E402
import matplotlib  # noqa: E402
from featherstar.cosim.scene.data import scene_from_dict  # noqa: E402
from featherstar.cosim.swimmer.run import run_scene  # noqa: E402
from featherstar.dashboard.monolithic import run_monolithic  # noqa: E402
from featherstar.fmu_src.feather import feather_model  # noqa: E402

from bench._rhs_cost import rhs_ns_per_evaluation  # noqa: E402

RESULTS = ROOT / "docs" / "results"
OLD_COMMIT = "32dc597"
SCENE = ROOT / "cosim" / "scenes" / "kinematic.toml"
MORPHOLOGIES = ("plain", "chordwise", "spanwise")
INPUT_SAMPLE = [0.3, 1.0, 5.0, 0.0]  # a root mid-stroke: angle, rate, acceleration, no flow


def log(message: str) -> None:
    print(message, flush=True)


# ----------------------------------------------------------------------------- the old code

def export_old_tree(target: Path) -> Path:
    """The packages of commit OLD_COMMIT (top-level fmu_src, cosim, hil, optimizer then) under `target`."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", OLD_COMMIT, "fmu_src", "cosim", "hil", "optimizer"],
                             check=True, capture_output=True).stdout
    target.mkdir(parents=True, exist_ok=True)
    subprocess.run(["tar", "-x", "-C", str(target)], input=archive, check=True)
    return target


def in_old_tree(old: Path, code: str, cache: Path) -> str:
    """Run `code` with the old fmu_src first on the path; its stdout."""
    env = dict(os.environ, PYTHONPATH=str(old), FEATHERSTAR_CACHE=str(cache))
    result = subprocess.run([sys.executable, "-c", code], cwd=old, env=env, capture_output=True, text=True)
    if result.returncode:
        raise RuntimeError(f"old formulation failed:\n{result.stderr[-2000:]}")
    return result.stdout.strip()


def old_function(old: Path, morphology: str, n_units: int, cache: Path) -> ca.Function:
    path = cache / f"old_{morphology}_{n_units}.casadi"
    in_old_tree(old, "from fmu_src.feather import feather_model\n"
                     f"open({str(path)!r}, 'w').write(feather_model({morphology!r}, {n_units}).function().serialize())",
                cache)
    return ca.Function.deserialize(path.read_text())


# ----------------------------------------------------------------------------- 1. RHS cost

def rhs_costs(sizes: Sequence[int], old: Path, cache: Path, old_sizes: Sequence[int]) -> list[dict[str, Any]]:
    rows = []
    for morphology in MORPHOLOGIES:
        for n_units in sizes:
            model = feather_model(morphology, n_units)
            x = np.full(model.x.numel(), 0.01)
            p = model.parameter_vector()
            function = model.function()
            both = ca.Function("rhs_y", [model.x, model.u, model.p], [ca.vertcat(model.xdot, model.y)])
            row = {"morphology": morphology, "n_units": n_units, "formulation": "chain",
                   "states": model.x.numel(), "instructions": function.n_instructions(),
                   "xdot": rhs_ns_per_evaluation(function, x, INPUT_SAMPLE, p),
                   "xdot_and_outputs": rhs_ns_per_evaluation(both, x, INPUT_SAMPLE, p)}
            rows.append(row)
            log(f"RHS chain {morphology:9s} N={n_units:2d}: {row['xdot']['ns_median'] / 1e3:6.2f} us "
                f"(+outputs {row['xdot_and_outputs']['ns_median'] / 1e3:6.2f} us)")
            if n_units in old_sizes and morphology != "spanwise":
                dense = old_function(old, morphology, n_units, cache)
                both = ca.Function("rhs_y", dense.sx_in(), [ca.vertcat(*dense.call(dense.sx_in()))])
                old_row = {"morphology": morphology, "n_units": n_units, "formulation": "dense (32dc597)",
                           "states": model.x.numel(), "instructions": dense.n_instructions(),
                           "xdot": rhs_ns_per_evaluation(dense, x, INPUT_SAMPLE, p),
                           "xdot_and_outputs": rhs_ns_per_evaluation(both, x, INPUT_SAMPLE, p)}
                rows.append(old_row)
                log(f"RHS dense {morphology:9s} N={n_units:2d}: {old_row['xdot']['ns_median'] / 1e3:6.2f} us "
                    f"(+outputs {old_row['xdot_and_outputs']['ns_median'] / 1e3:6.2f} us)")
    return rows


# ----------------------------------------------------------------------------- 2. builds

_BUILD_ONE = """
import sys, time
from pathlib import Path
from {package}.feather import feather_model
from {package}.export import build_fmu
started = time.perf_counter()
path = build_fmu(feather_model({morphology!r}, {n_units}), Path({out!r}), force=True)
print(time.perf_counter() - started)
print(path)
"""


def build_feather(morphology: str, n_units: int, out: Path, cache: Path, tree: Path = ROOT) -> dict[str, Any]:
    """Build one feather FMU in a child process under /usr/bin/time -v: wall s, peak RSS."""
    package = "featherstar.fmu_src" if tree == ROOT else "fmu_src"   # the old tree predates the package move
    code = _BUILD_ONE.format(package=package, morphology=morphology, n_units=n_units, out=str(out))
    env = dict(os.environ, PYTHONPATH=str(tree), FEATHERSTAR_CACHE=str(cache))
    result = subprocess.run(["/usr/bin/time", "-v", sys.executable, "-c", code], cwd=tree, env=env,
                            capture_output=True, text=True)
    if result.returncode:
        raise RuntimeError(f"building {morphology} N={n_units} failed:\n{result.stderr[-2000:]}")
    seconds, path = result.stdout.strip().splitlines()[-2:]
    rss_kb = next(int(line.split(":")[1]) for line in result.stderr.splitlines() if "Maximum resident" in line)
    return {"morphology": morphology, "n_units": n_units, "build_s": float(seconds), "peak_rss_MB": rss_kb / 1024,
            "fmu": path}


def cold_build_all(cache: Path) -> dict[str, Any]:
    code = ("import time\nfrom featherstar.fmu_src.catalog import MODELS\nfrom featherstar.fmu_src.export import build_fmu\n"
            "t = time.perf_counter()\nfor build in MODELS.values(): build_fmu(build(), force=True)\n"
            "print(time.perf_counter() - t)")
    env = dict(os.environ, PYTHONPATH=str(ROOT), FEATHERSTAR_CACHE=str(cache))
    result = subprocess.run(["/usr/bin/time", "-v", sys.executable, "-c", code], cwd=ROOT, env=env,
                            capture_output=True, text=True, check=True)
    rss_kb = next(int(line.split(":")[1]) for line in result.stderr.splitlines() if "Maximum resident" in line)
    return {"all_five_s": float(result.stdout.strip().splitlines()[-1]), "peak_rss_MB": rss_kb / 1024}


# ----------------------------------------------------------------------------- 3./4. scene runs

# The old model has no sheet damping: the head-to-head runs today's model without it too, so that
# the two solve the same equations (the shipped damping's own effect is in section 5).
SAME_PHYSICS = {"retardation_time_s": 0.0}


def scene_with_fmu(fmu: Path, rtol: float = 1e-6, morphology: str = "chordwise",
                   extra: dict[str, float] | None = None) -> Any:
    """The kinematic scene with its feather block running the given FMU file."""
    data = tomllib.loads(SCENE.read_text())
    feather = data["blocks"]["feather"]
    # The catalog feather accepts the other morphologies' parameters; a bare FMU only its own.
    parameters = {"width_ratio": feather["parameters"]["width_ratio"]} if morphology == "chordwise" else {}
    parameters.update(extra or {})
    data["blocks"]["feather"] = {"kind": "fmu", "fmu": str(fmu), "parameters": parameters}
    data["master"]["rtol"] = rtol
    data["master"]["atol"] = rtol * 1e-2
    return scene_from_dict(data, name=f"kinematic-{fmu.stem}", source=str(SCENE))


def timed_run(label: str, run) -> dict[str, Any]:
    started = time.perf_counter()
    result = run()
    wall = time.perf_counter() - started
    stats = result.summary.get("stats", {})
    return {"label": label, "wall_s": wall, "thrust_ratio": float(result.summary["thrust_ratio"]),
            "mean_thrust_N": float(result.summary.get("mean_thrust_N", float("nan"))),
            "steps": stats.get("steps"), "rhs_evals": stats.get("rhs_evals")}


_OLD_MASTER_RUN = """
import json, time, tomllib
from cosim.run import run_scene
from cosim.scene import scene_from_dict
data = tomllib.loads(open({scene!r}).read())
data["blocks"]["feather"] = {{"kind": "fmu", "fmu": {fmu!r}, "parameters": {{"width_ratio": 7.5}}}}
scene = scene_from_dict(data, name="kinematic-old", source={scene!r})
run_scene(scene)   # untimed: first touch of the FMU
started = time.perf_counter()
result = run_scene(scene)
wall = time.perf_counter() - started
stats = result.summary.get("stats", {{}})
print(json.dumps({{"wall_s": wall, "thrust_ratio": result.summary["thrust_ratio"],
                  "mean_thrust_N": result.summary.get("mean_thrust_N"), "steps": stats.get("steps"),
                  "rhs_evals": stats.get("rhs_evals")}}))
"""


def old_master_run(old: Path, old_fmu: Path, cache: Path) -> dict[str, Any]:
    """The kinematic scene as it ran before this change: commit OLD_COMMIT's master (Python
    right-hand side) on its dense-formulation FMU, in a child process with the old tree first on
    the path; the wall time of run_scene, measured inside the child."""
    code = _OLD_MASTER_RUN.format(scene=str(old / "cosim" / "scenes" / "kinematic.toml"), fmu=str(old_fmu))
    row = json.loads(in_old_tree(old, code, cache).splitlines()[-1])
    return {"label": f"old master + dense FMU ({OLD_COMMIT})", **row}


def head_to_head(new_fmu: Path, old_fmu: Path, repeats: int, old: Path, cache: Path) -> dict[str, Any]:
    same = {f"feather.{k}": v for k, v in SAME_PHYSICS.items()}
    # each contender returns its row (wall time, TR, steps); the old master times itself in its child
    runs = {
        "master (chain FMU)": lambda: timed_run("master", lambda: run_scene(scene_with_fmu(new_fmu, extra=SAME_PHYSICS))),
        "monolithic compiled (chain)": lambda: timed_run("monolithic", lambda: run_monolithic(
            "kinematic", same, rtol=1e-6, atol=1e-8, method="adams", compiled=True)),
        "master (dense FMU, 32dc597)": lambda: timed_run("dense", lambda: run_scene(scene_with_fmu(old_fmu))),
        f"old master + dense FMU ({OLD_COMMIT})": lambda: old_master_run(old, old_fmu, cache),
    }
    run_monolithic("kinematic", same, rtol=1e-6, atol=1e-8, method="adams", compiled=True)  # compile once, untimed
    samples: dict[str, list[dict[str, Any]]] = {label: [] for label in runs}
    labels = list(runs)
    for r in range(repeats):
        shift = r % len(labels)
        for label in labels[shift:] + labels[:shift]:  # rotate the order: drift hits all alike
            samples[label].append(runs[label]())
            last = samples[label][-1]
            log(f"  {label:30s} {last['wall_s']:6.2f} s  TR {last['thrust_ratio']:.3f}  steps {last['steps']}")
    summary = {label: {"median_wall_s": statistics.median(s["wall_s"] for s in rows),
                       "walls_s": [s["wall_s"] for s in rows], "thrust_ratio": rows[0]["thrust_ratio"],
                       "mean_thrust_N": rows[0]["mean_thrust_N"], "steps": rows[0]["steps"],
                       "rhs_evals": rows[0]["rhs_evals"]} for label, rows in samples.items()}
    band = [timed_run(f"dense rtol {rtol:g}", lambda: run_scene(scene_with_fmu(old_fmu, rtol)))
            for rtol in (1e-6, 1e-7, 1e-8)]
    trs = [b["thrust_ratio"] for b in band]
    # today's model over the same tolerances: do the two converge to the same TR?
    new_band = [timed_run(f"chain rtol {rtol:g}", lambda: run_scene(scene_with_fmu(new_fmu, rtol, extra=SAME_PHYSICS)))
                for rtol in (1e-6, 1e-7, 1e-8)]
    new_trs = [b["thrust_ratio"] for b in new_band]
    new, mono, old_fmu_new_master, old_everything = (summary[label]["median_wall_s"] for label in labels)
    new_tr = summary[labels[0]]["thrust_ratio"]
    return {"runs": summary, "old_chaos_band": {"runs": band, "thrust_ratio_min": min(trs), "thrust_ratio_max": max(trs)},
            "master_over_monolithic": new / mono,
            # the ratio: today's master and model against both as they were at OLD_COMMIT
            "master_over_old_master": new / old_everything,
            # the model's share alone: the old FMU through today's master
            "master_over_old_fmu_on_new_master": new / old_fmu_new_master,
            "new_tr_in_old_band": min(trs) <= new_tr <= max(trs),
            "new_chaos_band": {"runs": new_band, "thrust_ratio_min": min(new_trs), "thrust_ratio_max": max(new_trs)},
            "bands_overlap": min(new_trs) <= max(trs) and min(trs) <= max(new_trs),
            "tr_difference_at_rtol_1e-8": new_trs[-1] - trs[-1]}


def run_time_vs_n(sizes: Sequence[int], fmus: dict[tuple[str, int], Path]) -> list[dict[str, Any]]:
    rows = []
    for (morphology, n_units), fmu in sorted(fmus.items()):
        if n_units not in sizes:
            continue
        row = timed_run(f"{morphology} N={n_units}", lambda: run_scene(scene_with_fmu(fmu, morphology=morphology)))
        rows.append({"morphology": morphology, "n_units": n_units, **row})
        log(f"6 periods {morphology:9s} N={n_units:2d}: {row['wall_s']:6.2f} s  TR {row['thrust_ratio']:.3f}  "
            f"steps {row['steps']}  RHS evaluations {row['rhs_evals']}")
    return rows


STEP_VARIANTS = {
    "as shipped": {},
    "stop stiffness / 10": {"feather.contact_stiffness_Nm_rad_m": 1.0},
    "stop smoothing x 6 (3 deg)": {"feather.contact_smoothing_rad": 0.05236},
    "stop damping 0": {"feather.contact_damping_Nms_rad_m": 0.0},
    "bending stiffness E / 10": {"feather.youngs_modulus_Pa": 1.5e8},
    "no sheet damping (retardation 0)": {"feather.retardation_time_s": 0.0},
    "BDF instead of Adams": {"master.method": "bdf"},
}

# The sweep geometry whose undamped chain rang at tens of kHz (docs/model.md, material damping):
# spanwise, l = 60 mm, LR 1.04, the paper's 0.1 / 0.5 / 0 s stroke, the first 0.2 s on the test bed.
SHORT_SPANWISE = {"feather.morphology": "spanwise", "feather.width_m": 0.12, "feather.length_m": 0.06,
                  "feather.length_ratio": 0.06 / 0.0575, "controller.t_up_s": 0.1, "controller.t_hold_up_s": 0.0,
                  "controller.t_down_s": 0.5, "controller.t_hold_down_s": 0.0, "master.t_end_s": 0.2}


def step_budget() -> list[dict[str, Any]]:
    """Steps and RHS evaluations of the chordwise kinematic scene when one suspect is relaxed at a
    time: what sets the step size (the variants change the physics; they are probes, not fixes)."""
    rows = []
    for label, overrides in STEP_VARIANTS.items():
        row = {"variant": label, "overrides": overrides, **timed_run(label, lambda: run_scene("kinematic", overrides))}
        rows.append(row)
        log(f"  {label:30s} steps {row['steps']:6d}  RHS evaluations {row['rhs_evals']:6d}  "
            f"{row['wall_s']:5.2f} s  TR {row['thrust_ratio']:.3f}")
    for label, extra in (("short spanwise, as shipped", {}),
                         ("short spanwise, no sheet damping", {"feather.retardation_time_s": 0.0})):
        started = time.perf_counter()
        result = run_scene("testbed", {**SHORT_SPANWISE, **extra}, outputs=["feather.flap_angle_rad"])
        stats = result.summary["stats"]
        flap = result["feather.flap_angle_rad"]
        row = {"variant": label, "overrides": {**SHORT_SPANWISE, **extra}, "wall_s": time.perf_counter() - started,
               "steps": stats["steps"], "rhs_evals": stats["rhs_evals"],
               "flap_angle_range_rad": [float(flap.min()), float(flap.max())]}
        rows.append(row)
        log(f"  {label:30s} steps {row['steps']:8d}  RHS evaluations {row['rhs_evals']:8d}  {row['wall_s']:6.2f} s  "
            f"flap {row['flap_angle_range_rad'][0]:.5f}..{row['flap_angle_range_rad'][1]:.5f} rad")
    return rows


# ----------------------------------------------------------------------------- report

def plot(result: dict[str, Any], path: Path) -> None:
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from featherstar.cosim.plotstyle import save_figure

    fig, (ax_rhs, ax_run, ax_build) = plt.subplots(1, 3, figsize=(15, 4.5))
    for morphology, color in zip(MORPHOLOGIES, ("C0", "C1", "C2")):
        for formulation, style in (("chain", "-o"), ("dense (32dc597)", "--s")):
            rows = [r for r in result["rhs"] if r["morphology"] == morphology and r["formulation"] == formulation]
            if rows:
                ax_rhs.loglog([r["n_units"] for r in rows], [r["xdot"]["ns_median"] / 1e3 for r in rows], style,
                              color=color, label=f"{morphology}, {formulation}")
        rows = [r for r in result["run_time_vs_n"] if r["morphology"] == morphology]
        if rows:
            ax_run.loglog([r["n_units"] for r in rows], [r["wall_s"] for r in rows], "-o", color=color, label=morphology)
        rows = [r for r in result["builds"]["per_size"] if r["morphology"] == morphology]
        if rows:
            ax_build.semilogx([r["n_units"] for r in rows], [r["build_s"] for r in rows], "-o", color=color,
                              label=morphology)
    sizes = sorted({r["n_units"] for r in result["rhs"]})
    first = [r for r in result["rhs"] if r["morphology"] == "chordwise" and r["formulation"] == "chain"][0]
    ax_rhs.loglog(sizes, [first["xdot"]["ns_median"] / 1e3 * n / sizes[0] for n in sizes], ":", color="0.5",
                  label="∝ N")
    ax_rhs.set(xlabel="N units", ylabel="µs per RHS evaluation (compiled)", title="RHS cost")
    ax_run.set(xlabel="N units", ylabel="wall time (s)", title="6 periods, kinematic scene, FMU master")
    ax_build.set(xlabel="N units", ylabel="build time, cold (s)", title="FMU build time")
    for ax in (ax_rhs, ax_run, ax_build):
        ax.set_xticks(sizes, [str(n) for n in sizes])
        ax.minorticks_off()
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="N = 5 and 10 only, one repeat")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each head-to-head contender")
    parser.add_argument("--out", type=Path, default=RESULTS, help="directory for the JSON and the plot")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    sizes = (5, 10) if args.quick else (5, 10, 20, 40)
    repeats = 1 if args.quick else args.repeats
    args.out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    result: dict[str, Any] = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                                          "load_average_at_start": os.getloadavg()},
                              "old_commit": OLD_COMMIT, "sizes": list(sizes)}
    with tempfile.TemporaryDirectory(prefix="featherstar-speed-") as tmp:
        work = Path(tmp)
        old = export_old_tree(work / "old")
        log("1. compiled RHS cost")
        result["rhs"] = rhs_costs(sizes, old, work, old_sizes=(5, 10))

        log("2. FMU builds")
        result["builds"] = {"cold_all_five": cold_build_all(work / "cold-cache")}
        log(f"  all five shipped FMUs cold: {result['builds']['cold_all_five']['all_five_s']:.1f} s")
        per_size, fmus = [], {}
        for morphology in ("chordwise", "plain"):
            for n_units in sizes:
                row = build_feather(morphology, n_units, work / f"fmus-{morphology}-{n_units}", work / "size-cache")
                per_size.append(row)
                fmus[(morphology, n_units)] = Path(row["fmu"])
                log(f"  {morphology:9s} N={n_units:2d}: {row['build_s']:6.1f} s, peak RSS {row['peak_rss_MB']:.0f} MB")
        result["builds"]["per_size"] = per_size
        old_build = build_feather("chordwise", 10, work / "fmus-old", work / "old-cache", tree=old)
        result["builds"]["old_chordwise_10"] = old_build
        log(f"  dense (32dc597) chordwise N=10: {old_build['build_s']:.1f} s, peak RSS {old_build['peak_rss_MB']:.0f} MB")

        log("3. chordwise kinematic scene, 6 periods, rtol 1e-6")
        result["head_to_head"] = head_to_head(fmus[("chordwise", 10)], Path(old_build["fmu"]), repeats, old,
                                              work / "old-cache")
        log("4. run time against N")
        result["run_time_vs_n"] = run_time_vs_n(sizes, fmus)
    log("5. what sets the step size (chordwise N = 10, kinematic scene)")
    result["step_budget"] = step_budget()
    result["bench_wall_s"] = time.perf_counter() - started
    json_path = args.out / "feather_speed.json"
    json_path.write_text(json.dumps(result, indent=2))
    plot(result, args.out / "feather_speed.png")
    h = result["head_to_head"]
    log(f"master/monolithic {h['master_over_monolithic']:.2f}, master/(old master + old FMU) "
        f"{h['master_over_old_master']:.2f}, master/(old FMU on today's master) "
        f"{h['master_over_old_fmu_on_new_master']:.2f}, TR in the old band: {h['new_tr_in_old_band']}, bands overlap: "
        f"{h['bands_overlap']}, TR difference at rtol 1e-8: {h['tr_difference_at_rtol_1e-8']:.2g}; wrote {json_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
