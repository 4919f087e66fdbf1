"""30 iterations of `featherstar optimize testbed`: sequential against constant-liar batches on
local worker processes, wall time and the best TR each finds.

Runs the command line a user would (`featherstar optimize testbed --iterations 30 --seed S`, and
the same with `--batch-size K --workers K`), for several seeds, alternating the two modes so that
drift on a shared machine hits both alike. The wall time includes process start, the FMU from the
user's cache, the 30 evaluations and the validation of the optimum and the baseline that the
command always runs. The best TR is the validated one from summary.json; batches change which
points the search visits, so compare the best TRs over the seed family, not run by run.

Writes docs/results/optimizer_speed.json and optimizer_speed.png.

    python bench/optimizer_speed.py [--seeds 1 2] [--batch-size 2] [--iterations 30] [--out DIR]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Sequence

import matplotlib

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"


def optimize(out: Path, iterations: int, seed: int, batch_size: int) -> dict[str, Any]:
    command = [sys.executable, "-m", "featherstar", "optimize", "testbed", "--iterations", str(iterations),
               "--seed", str(seed), "--out", str(out)]
    if batch_size > 1:
        command += ["--batch-size", str(batch_size), "--workers", str(batch_size)]
    started = time.perf_counter()
    result = subprocess.run(command, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - started
    if result.returncode:
        raise RuntimeError(f"{' '.join(command)} failed:\n{result.stderr[-3000:]}")
    summary = json.loads((out / "summary.json").read_text())
    return {"seed": seed, "batch_size": batch_size, "wall_s": wall, "command": " ".join(command[2:]),
            "best_thrust_ratio": summary["thrust_ratio"], "best_thrust_ratio_sd": summary["thrust_ratio_sd"],
            "estimated_thrust_ratio": summary["estimated_thrust_ratio"],
            "baseline_thrust_ratio": summary["baseline_thrust_ratio"], "best_params": summary["best_params"]}


def plot(result: dict[str, Any], path: Path) -> None:
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from featherstar.cosim.plotstyle import save_figure

    fig, (ax_time, ax_tr) = plt.subplots(1, 2, figsize=(10, 4))
    for k, (mode, rows) in enumerate(result["runs"].items()):
        seeds = [r["seed"] for r in rows]
        ax_time.bar([s + 0.35 * k for s in seeds], [r["wall_s"] for r in rows], width=0.35, label=mode)
        ax_tr.bar([s + 0.35 * k for s in seeds], [r["best_thrust_ratio"] for r in rows], width=0.35,
                  yerr=[r["best_thrust_ratio_sd"] for r in rows], label=mode)
    ax_time.axhline(60, color="0.4", ls=":", label="goal 60 s")
    ax_time.set(xlabel="seed", ylabel="wall time (s)", title=f"{result['iterations']} iterations, testbed")
    ax_tr.set(xlabel="seed", ylabel="validated best TR", title="best TR found")
    trs = [r["best_thrust_ratio"] for rows in result["runs"].values() for r in rows]
    ax_tr.set_ylim(min(trs) - 0.1, max(trs) + 0.1)
    seeds = sorted({r["seed"] for rows in result["runs"].values() for r in rows})
    for ax in (ax_time, ax_tr):
        ax.set_xticks([s + 0.175 for s in seeds], [str(s) for s in seeds])
        ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--batch-size", type=int, default=2)
    parser.add_argument("--iterations", type=int, default=30)
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    modes = {"sequential": 1, f"batch {args.batch_size} on {args.batch_size} processes": args.batch_size}
    runs: dict[str, list[dict[str, Any]]] = {mode: [] for mode in modes}
    work = Path(tempfile.mkdtemp(prefix="featherstar-optimizer-speed-"))
    try:
        for i, seed in enumerate(args.seeds):
            order = list(modes.items()) if i % 2 == 0 else list(modes.items())[::-1]
            for mode, batch_size in order:
                row = optimize(work / f"{batch_size}-{seed}", args.iterations, seed, batch_size)
                runs[mode].append(row)
                print(f"{mode:28s} seed {seed}: {row['wall_s']:6.1f} s, best TR {row['best_thrust_ratio']:.3f} "
                      f"± {row['best_thrust_ratio_sd']:.3f}", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    for rows in runs.values():
        rows.sort(key=lambda r: r["seed"])
    result = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "load_average": os.getloadavg()},
              "iterations": args.iterations, "runs": runs,
              "median_wall_s": {mode: statistics.median(r["wall_s"] for r in rows) for mode, rows in runs.items()},
              "best_thrust_ratio": {mode: max(r["best_thrust_ratio"] for r in rows) for mode, rows in runs.items()}}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "optimizer_speed.json").write_text(json.dumps(result, indent=2) + "\n")
    plot(result, args.out / "optimizer_speed.png")
    print(json.dumps({k: result[k] for k in ("median_wall_s", "best_thrust_ratio")}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
