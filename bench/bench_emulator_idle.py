"""The emulator's CPU use when nobody talks to it: `featherstar emulate` started, left alone for
--seconds after it listens, then utime + stime of the process over that time, as a share of one
core. Writes docs/results/emulator_idle_cpu.json (with --out).

    python bench/bench_emulator_idle.py --plant fmu --seconds 20 --out docs/results/emulator_idle_cpu.json
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

from featherstar.hil.emulator import spawn_emulator

_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / _TICKS


def measure(plant: str, seconds: float, settle_s: float) -> dict:
    with spawn_emulator(plant=plant, seed=1, start_timeout_s=600) as emulator:
        time.sleep(settle_s)        # start-up transients (FMU load, first ticks) left out
        cpu0, wall0 = cpu_s(emulator.proc.pid), time.monotonic()
        time.sleep(seconds)
        cpu1, wall1 = cpu_s(emulator.proc.pid), time.monotonic()
    return {"plant": plant, "idle_s": wall1 - wall0, "cpu_s": cpu1 - cpu0,
            "cpu_share_of_one_core": (cpu1 - cpu0) / (wall1 - wall0)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", choices=("fmu", "flat-plate"), default="fmu")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--settle-s", type=float, default=3.0)
    parser.add_argument("--out", type=Path, metavar="DIR",
                        help="write emulator_idle_cpu.json here (default: print only)")
    args = parser.parse_args()
    result = measure(args.plant, args.seconds, args.settle_s)
    result.update(machine=platform.machine(), cpus=os.cpu_count(),
                  loadavg_1min=os.getloadavg()[0],
                  command=f"python bench/bench_emulator_idle.py --plant {args.plant} "
                          f"--seconds {args.seconds:g}")
    print(json.dumps(result, indent=2))
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "emulator_idle_cpu.json").write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
