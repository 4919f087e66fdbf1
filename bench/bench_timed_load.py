"""Valid-period share and TR of `featherstar run testbed --hardware ...` against the emulator,
streamed (clock=pc) and device-timed (clock=device), quiet and with busy processes competing
for the cores (`python -c "while True: pass"` x --busy).

    python bench/bench_timed_load.py --plant fmu --repeats 2 --out docs/results/timed_vs_streaming_load.json

(the PNG beside the JSON; `--plot JSON` redraws it). The 10-iteration `optimize --hardware`
under the same load is bench/bench_timed_optimize.py.

Each run is a fresh `featherstar run` process (4 stroke periods, 3 measured) against one
emulator process, SETTLE_S after the previous one (a bench waits for the feather to come to rest
before it tares); the busy processes start before the run and are killed after it. TR error is
against the mean quiet run of the same mode.
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


SETTLE_S = 10.0   # the feather rings for seconds after a run; a tare taken then is wrong


def one_run(emulator, clock: str, busy: int, periods: int) -> dict:
    time.sleep(SETTLE_S)
    with busy_processes(busy):
        with tempfile.TemporaryDirectory() as out:
            run = subprocess.run(
                [sys.executable, "-m", "featherstar", "run", "testbed", "--quiet", "--no-figure",
                 "--out", out,
                 "--hardware", f"servo={emulator.servo_url}&clock={clock}",
                 "--hardware", f"loadcell={emulator.loadcell_url}&clock={clock}",
                 "--set", f"master.periods={periods}", "--set", "metrics.settle_periods=1"],
                capture_output=True, text=True, timeout=300)
            summary_path = Path(out) / "summary.json"
            summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    validity = summary.get("validity") or {}
    used = summary.get("periods_used") or 0
    return {"clock": clock, "busy_processes": busy, "exit": run.returncode,
            "complete": summary.get("complete"), "periods_used": used,
            "valid_periods": validity.get("valid_periods"),
            "valid_share": (validity.get("valid_periods") or 0) / used if used else 0.0,
            "thrust_ratio": summary.get("thrust_ratio"),
            "mean_thrust_N": summary.get("mean_thrust_N"),
            "deadline_misses": summary.get("deadline_misses"),
            "lags": summary.get("lags"), "gaps": summary.get("gaps"),
            "error": (run.stderr.strip().splitlines() or [""])[-1] if run.returncode else ""}


def _number(x) -> float | None:
    """A summary's number (NaN is written as the string 'nan'), or None."""
    try:
        value = float(x)
    except (TypeError, ValueError):
        return None
    return value if value == value else None


def summarise(runs: list[dict], busy: int) -> dict:
    """Per mode and load: runs, complete runs, valid-period share, TR error vs the quiet mean."""
    table = {}
    for clock in ("pc", "device"):
        quiet = [_number(r["thrust_ratio"]) for r in runs
                 if r["clock"] == clock and not r["busy_processes"] and r["complete"]]
        quiet = [q for q in quiet if q is not None]
        tr_quiet = sum(quiet) / len(quiet) if quiet else None
        for load in (0, busy):
            rs = [r for r in runs if r["clock"] == clock and r["busy_processes"] == load]
            trs = [_number(r["thrust_ratio"]) for r in rs if r["complete"]]
            errors = [abs(tr / tr_quiet - 1) for tr in trs if tr is not None and tr_quiet]
            table[f"{clock}, {load} busy"] = {
                "runs": len(rs), "complete": sum(bool(r["complete"]) for r in rs),
                "valid_share_min": min(r["valid_share"] for r in rs),
                "valid_share_mean": sum(r["valid_share"] for r in rs) / len(rs),
                "tr_of_complete_runs": trs, "tr_quiet_mean": tr_quiet,
                "tr_error_vs_quiet_max": max(errors) if errors else None}
    return table


def plot(result: dict, path: Path) -> None:
    """Valid-period share and TR of every run, by mode and load."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = result["runs"]
    cases = [(c, b) for c in ("pc", "device") for b in sorted({r["busy_processes"] for r in runs})]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    for i, (clock, busy) in enumerate(cases):
        rs = [r for r in runs if r["clock"] == clock and r["busy_processes"] == busy]
        ax1.plot([i] * len(rs), [r["valid_share"] for r in rs], "o", color="tab:blue")
        trs = [_number(r["thrust_ratio"]) for r in rs if r["complete"]]
        ax2.plot([i] * len(trs), trs, "s", color="tab:green")
    labels = [f"clock={c}\n{b} busy" for c, b in cases]
    for ax in (ax1, ax2):
        ax.set_xticks(range(len(cases)), labels)
        ax.set_xlim(-0.5, len(cases) - 0.5)
        ax.set_xlabel("clock mode and competing load")
    ax1.axhline(0.9, color="k", ls="--", lw=0.8, label="90 % (issue 25)")
    ax1.set_ylabel("valid share of the measured periods")
    ax1.set_ylim(-0.05, 1.05)
    ax1.legend(fontsize=8)
    quiet = (result["summary"].get("device, 0 busy") or {}).get("tr_quiet_mean")
    if quiet:
        ax2.axhspan(quiet * 0.98, quiet * 1.02, color="0.85", label="device quiet mean ±2 %")
        ax2.legend(fontsize=8)
    ax2.set_ylabel("TR of complete runs")
    fig.suptitle("featherstar run testbed --hardware: streamed vs device-timed, quiet vs loaded")
    fig.tight_layout()
    save_figure(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", choices=("fmu", "flat-plate"), default="fmu")
    parser.add_argument("--busy", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--periods", type=int, default=4)
    parser.add_argument("--out", type=Path, metavar="DIR",
                        help="write timed_vs_streaming_load.json and .png here (default: print only)")
    parser.add_argument("--plot", type=Path, metavar="JSON", help="only draw the PNG of a result")
    args = parser.parse_args()
    if args.plot:
        plot(json.loads(args.plot.read_text()), args.plot.with_suffix(".png"))
        return
    runs = []
    with spawn_emulator(plant=args.plant, seed=1, start_timeout_s=600) as emulator:
        for _ in range(args.repeats):
            for clock in ("pc", "device"):
                for busy in (0, args.busy):
                    runs.append(one_run(emulator, clock, busy, args.periods))
                    print(json.dumps(runs[-1]), flush=True)
    table = summarise(runs, args.busy)
    result = {"command": " ".join(["python", *sys.argv]), "plant": args.plant,
              "cpus": os.cpu_count(), "machine": platform.machine(),
              "note": "the machine is shared: other processes add to the busy ones",
              "summary": table, "runs": runs}
    print(json.dumps(table, indent=2))
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "timed_vs_streaming_load.json").write_text(json.dumps(result, indent=2) + "\n")
        plot(result, args.out / "timed_vs_streaming_load.png")


if __name__ == "__main__":
    main()
