"""Paced hardware-in-the-loop loop rate over loopback against the bench emulator.

At 100, 250 and 500 Hz, each step sends the servo setpoint, reads back its position and reads
the load cell (3 Modbus transactions), through the real blocks and `run_paced`, with the
emulator in a child process as a real device would be. Also measures the free-running step
rate. Writes bench/results/hil_loop_rate.json and .png.

    python bench/hil_loop_rate.py [--quick]     (about 30 s; --quick about 10 s)
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import matplotlib
import pymodbus

from featherstar.hil.blocks import LoadCell, Servo
from featherstar.hil.emulator import spawn_emulator
from featherstar.hil.pacing import run_paced

RATES_HZ = (100, 250, 500)
RESULTS = Path(__file__).resolve().parent / "results"


def make_step(servo: Servo, cell: LoadCell):
    def step(t_s: float, h_s: float) -> dict[str, float]:
        if h_s > 0:
            servo.do_step(t_s - h_s, h_s)
            cell.do_step(t_s - h_s, h_s)
        servo.set_inputs({"setpoint_rad": 0.6 * math.sin(2 * math.pi * t_s / 1.5)})
        return {**servo.get_outputs(), **cell.get_outputs()}
    return step


def free_running(servo: Servo, cell: LoadCell, duration_s: float) -> dict[str, float]:
    durations = []
    t_end = time.monotonic() + duration_s
    while (t := time.monotonic()) < t_end:
        servo.do_step(0.0, 0.002)
        cell.do_step(0.0, 0.002)
        durations.append(time.monotonic() - t)
    durations.sort()
    return {"steps_per_s": len(durations) / duration_s,
            "step_p50_ms": 1e3 * durations[len(durations) // 2],
            "step_p99_ms": 1e3 * durations[int(0.99 * len(durations))],
            "step_max_ms": 1e3 * durations[-1]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="about 10 s instead of 30 s")
    parser.add_argument("--out", type=Path, default=RESULTS, help=f"where the JSON and plot go (default {RESULTS})")
    args = parser.parse_args()
    duration_s = 2.5 if args.quick else 8.0
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    result: dict[str, object] = {
        "transactions_per_step": 3, "duration_s_per_rate": duration_s,
        "machine": {"cpus": os.cpu_count(), "load_avg_1min_at_start": os.getloadavg()[0],
                    "python": platform.python_version(), "pymodbus": pymodbus.__version__},
        "rates": []}
    step_ms: dict[int, list[float]] = {}
    emu = spawn_emulator(seed=0)
    servo = Servo("servo", emu.servo_url, timeout_s=0.05)
    cell = LoadCell("cell", emu.loadcell_url, timeout_s=0.05, stale_s=None)
    try:
        servo.start(0.0)
        cell.start(0.0)
        result["free_running"] = free_running(servo, cell, 0.5 if args.quick else 1.0)
        for rate_hz in RATES_HZ:
            with tempfile.TemporaryDirectory() as out_dir:
                run = run_paced(make_step(servo, cell), rate_hz, duration_s, out_dir)
                with open(run.samples_csv, newline="") as f:
                    step_ms[rate_hz] = [1e3 * float(r["step_s"]) for r in csv.DictReader(f)]
            s = run.stats
            result["rates"].append({
                "rate_hz": rate_hz, "n_samples": run.n_samples,
                "achieved_hz": (run.n_samples - 1) / duration_s,
                "n_misses": s["n_misses"], "miss_fraction": s["miss_fraction"],
                "n_skipped": s["n_skipped"],
                "late_p50_ms": 1e3 * s["late_p50_s"], "late_p99_ms": 1e3 * s["late_p99_s"],
                "late_max_ms": 1e3 * s["late_max_s"],
                "busy_p50_ms": 1e3 * s["busy_p50_s"], "busy_p99_ms": 1e3 * s["busy_p99_s"],
                "busy_max_ms": 1e3 * s["busy_max_s"]})
    finally:
        servo.close()
        cell.close()
        emu.stop()
    result["machine"]["load_avg_1min_at_end"] = os.getloadavg()[0]
    (out / "hil_loop_rate.json").write_text(json.dumps(result, indent=2) + "\n")
    plot(result, step_ms, out)
    for r in result["rates"]:
        print(f"{r['rate_hz']:4d} Hz: achieved {r['achieved_hz']:6.1f} Hz, misses "
              f"{r['n_misses']}/{r['n_samples']} ({100 * r['miss_fraction']:.2f} %), skipped "
              f"{r['n_skipped']}, step p50/p99 {r['busy_p50_ms']:.2f}/{r['busy_p99_ms']:.2f} ms, "
              f"late p99 {r['late_p99_ms']:.2f} ms")
    fr = result["free_running"]
    print(f"free running: {fr['steps_per_s']:.0f} steps/s, step p50/p99 "
          f"{fr['step_p50_ms']:.2f}/{fr['step_p99_ms']:.2f} ms")
    print(f"wrote {out / 'hil_loop_rate.json'} and .png")
    return 0


def plot(result: dict, step_ms: dict[int, list[float]], out: Path) -> None:
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from featherstar.cosim.plotstyle import save_figure
    fig, (ax_cdf, ax_miss) = plt.subplots(1, 2, figsize=(9, 3.5))
    for rate_hz, values in step_ms.items():
        values = sorted(values[1:])       # the first sample does no I/O
        ax_cdf.plot(values, [i / len(values) for i in range(len(values))], label=f"{rate_hz} Hz")
        ax_cdf.axvline(1e3 / rate_hz, ls=":", color=ax_cdf.lines[-1].get_color())
    ax_cdf.set_xscale("log")
    ax_cdf.set_xlabel("step time (ms; dotted: the period)")
    ax_cdf.set_ylabel("fraction of steps")
    ax_cdf.legend()
    rates = result["rates"]
    ax_miss.bar([str(r["rate_hz"]) for r in rates], [100 * r["miss_fraction"] for r in rates])
    ax_miss.set_xlabel("loop rate (Hz)")
    ax_miss.set_ylabel("deadline misses (% of steps)")
    fig.suptitle("Paced HIL loop over loopback (servo write + read-back, load-cell read)")
    fig.tight_layout()
    save_figure(fig, out / "hil_loop_rate.png", dpi=110)


if __name__ == "__main__":
    sys.exit(main())
