"""A 10-iteration `featherstar optimize testbed --hardware ...` against the emulator, streamed
(clock=pc) and device-timed (clock=device), quiet and with busy processes competing for the
cores (`python -c "while True: pass"` x --busy): runs kept and discarded (and why), and the TR
of the same strokes quiet vs loaded.

    python bench/bench_timed_optimize.py --out docs/results/timed_optimize_load.json

Every study has the same --seed, so its random initial points are the same strokes quiet and
loaded; the later ones follow the measured TRs, so a stroke is compared only where both studies
evaluated it (the same parameters to 1e-9), and the baseline's validation is the same stroke in
every study. A study that pauses (three runs of one stroke discarded in a row) ends there: its
evaluations so far are counted. The busy processes start before the study and are killed after.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from featherstar.cosim.plotstyle import save_figure
from featherstar.hil.emulator import spawn_emulator

from _under_load import busy_processes
# Words of optimizer.bench.objective.discard_reasons that say the PC did not keep time.
TIMING_WORDS = ("late", "deadline", "data gap", "behind real time", "excluded")


def one_study(emulator, clock: str, busy: int, args: argparse.Namespace) -> dict:
    started = time.monotonic()
    with busy_processes(busy):
        with tempfile.TemporaryDirectory() as out:
            run = subprocess.run(
                [sys.executable, "-m", "featherstar", "optimize", "testbed", "--out", out,
                 "--seed", str(args.seed), "--iterations", str(args.iterations),
                 "--rest-s", str(args.rest_s),
                 "--validation-repeats", str(args.validation_repeats),
                 "--validation-periods", str(args.validation_periods),
                 # as the README's bench study: a brief stall discards one run, not the study
                 "--hardware", f"servo={emulator.servo_url}&clock={clock}&reconnect_s=3",
                 "--hardware", f"loadcell={emulator.loadcell_url}&clock={clock}&reconnect_s=3"],
                capture_output=True, text=True, timeout=3600)
            log = Path(out) / "evaluations.jsonl"
            records = [json.loads(x) for x in log.read_text().splitlines()] if log.exists() else []
    evaluations = [r for r in records if r["kind"] == "evaluation"]
    discarded = [r for r in records if r["kind"] == "discarded"]
    timing = [r for r in discarded if any(w in "; ".join(r["reasons"]) for w in TIMING_WORDS)]
    return {"clock": clock, "busy_processes": busy, "exit": run.returncode,
            "wall_s": time.monotonic() - started,
            "evaluations": len(evaluations), "discarded_runs": len(discarded),
            "discarded_for_timing": len(timing),
            "discard_reasons": [r["reasons"] for r in discarded][:10],
            "faults": [r["message"] for r in records if r["kind"] == "fault"],
            "kept_share": len(evaluations) / max(len(evaluations) + len(discarded), 1),
            "strokes": [{"params": r["params"], "thrust_ratio": r["thrust_ratio"],
                         "mean_thrust_N": r["mean_thrust_N"]} for r in evaluations],
            "validations": {r["controller"]: {"thrust_ratio": r["thrust_ratio"],
                                              "thrust_ratio_sd": r["thrust_ratio_sd"],
                                              "overrides": r["overrides"]}
                            for r in records if r["kind"] == "validation"},
            "error": (run.stderr.strip().splitlines() or [""])[-1] if run.returncode else ""}


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(abs(a[k] - b[k]) <= 1e-9 for k in a)


def compare(quiet: dict, loaded: dict) -> dict:
    """TR of the strokes both studies evaluated (loaded / quiet - 1), and of the baseline."""
    pairs = []
    for i, q in enumerate(quiet["strokes"]):
        match = [s for s in loaded["strokes"] if _same(s["params"], q["params"])]
        if match:
            pairs.append({"index": i, "tr_quiet": q["thrust_ratio"], "tr_loaded": match[0]["thrust_ratio"],
                          "tr_error": match[0]["thrust_ratio"] / q["thrust_ratio"] - 1})
    base = [s["validations"].get("baseline", {}).get("thrust_ratio") for s in (quiet, loaded)]
    return {"same_strokes": len(pairs), "pairs": pairs,
            "tr_error_max": max((abs(p["tr_error"]) for p in pairs), default=None),
            "baseline_validation_tr": base,
            "baseline_tr_error": base[1] / base[0] - 1 if None not in base else None}


def plot(result: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    studies = result["studies"]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    labels = [f"{s['clock']}\n{s['busy_processes']} busy" for s in studies]
    kept = [s["evaluations"] for s in studies]
    dropped = [s["discarded_runs"] for s in studies]
    x = range(len(studies))
    ax1.bar(x, kept, label="evaluations kept")
    ax1.bar(x, dropped, bottom=kept, label="runs discarded", color="tab:red")
    ax1.axhline(result["iterations"], color="k", lw=0.8, ls="--", label="iterations asked")
    ax1.set_xticks(list(x), labels)
    ax1.set_ylim(0, 1.15 * result["iterations"])     # the "asked" line above the bars
    ax1.set_xlabel("clock mode and competing load")
    ax1.set_ylabel("number of bench runs")
    ax1.set_title("10-iteration optimize --hardware")
    ax1.legend(fontsize=8)
    for clock, marker in (("pc", "o"), ("device", "s")):
        pairs = result["comparison"].get(clock, {}).get("pairs", [])
        if pairs:
            ax2.plot([p["tr_quiet"] for p in pairs], [p["tr_loaded"] for p in pairs], marker,
                     label=f"clock={clock} ({len(pairs)} same strokes)")
    repeat = result.get("quiet_repeat", {}).get("pairs", [])
    if repeat:   # the same strokes, two quiet studies: the feather's own run-to-run scatter
        ax2.plot([p["tr_quiet"] for p in repeat], [p["tr_loaded"] for p in repeat], "x", color="k",
                 label=f"clock=device, quiet vs quiet ({len(repeat)})")
    lo, hi = ax2.get_xlim()
    ax2.plot([lo, hi], [lo, hi], "k-", lw=0.6)
    ax2.fill_between([lo, hi], [lo * 0.98, hi * 0.98], [lo * 1.02, hi * 1.02], color="0.85",
                     label="±2 %")
    ax2.set_xlabel("TR, quiet")
    ax2.set_ylabel(f"TR, {result['busy']} busy processes")
    ax2.set_title("the same strokes, quiet vs loaded")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", choices=("fmu", "flat-plate"), default="fmu")
    parser.add_argument("--busy", type=int, default=2)
    parser.add_argument("--iterations", type=int, default=10)
    parser.add_argument("--seed", type=int, default=3)
    # the fmu feather rings for seconds after a run; a tare taken then offsets the next TR
    parser.add_argument("--rest-s", type=float, default=10.0)
    parser.add_argument("--validation-repeats", type=int, default=2)
    parser.add_argument("--validation-periods", type=int, default=2)
    parser.add_argument("--clocks", default="device,pc")
    parser.add_argument("--keep", type=Path, metavar="JSON",
                        help="take the studies of the other clocks from this earlier result")
    parser.add_argument("--out", type=Path, metavar="DIR",
                        help="write timed_optimize_load.json and .png here (default: print only)")
    parser.add_argument("--plot", type=Path, metavar="JSON", help="only draw the PNG of a result")
    args = parser.parse_args()
    if args.plot:
        plot(json.loads(args.plot.read_text()), args.plot.with_suffix(".png"))
        return
    studies = []
    with spawn_emulator(plant=args.plant, seed=1, start_timeout_s=600) as emulator:
        for clock in args.clocks.split(","):
            for busy in (0, args.busy):
                studies.append(one_study(emulator, clock, busy, args))
                print(json.dumps({k: v for k, v in studies[-1].items() if k != "strokes"}), flush=True)
    clocks = args.clocks.split(",")
    kept = []
    if args.keep:
        kept = [s for s in json.loads(args.keep.read_text())["studies"] if s["clock"] not in clocks]
        studies += kept
        clocks += sorted({s["clock"] for s in kept})
    comparison = {}
    for clock in clocks:
        quiet, loaded = (next(s for s in studies if s["clock"] == clock and s["busy_processes"] == b)
                         for b in (0, args.busy))
        comparison[clock] = compare(quiet, loaded)
    result = {"command": " ".join(["python", *sys.argv]), "plant": args.plant, "busy": args.busy,
              "iterations": args.iterations, "seed": args.seed, "cpus": os.cpu_count(),
              "machine": platform.machine(),
              "note": "the machine is shared: other processes add to the busy ones"
                      + (f"; the {', '.join(sorted({s['clock'] for s in kept}))} studies are from an "
                         f"earlier run of this script ({args.keep})" if kept else ""),
              "comparison": comparison, "studies": studies}
    print(json.dumps(comparison, indent=2))
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "timed_optimize_load.json").write_text(json.dumps(result, indent=2) + "\n")
        plot(result, args.out / "timed_optimize_load.png")


if __name__ == "__main__":
    main()
