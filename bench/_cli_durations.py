"""How long the documented commands take: `featherstar paper --quick`, `featherstar paper`,
`featherstar bench --quick` and the test suite (the README's command, which CI runs), timed here and merged into docs/results/cli_durations.json, the one source the
README, docs/ and `--help` quote (bench/_doc_numbers.py; tests/test_doc_numbers.py checks them).
A leading underscore: `featherstar bench` does not run it (it times `featherstar bench` itself).

    python bench/_cli_durations.py --only paper_quick       # one command, the others kept
    python bench/_cli_durations.py                          # every command, one after the other

Each entry: the command, its wall time, the machine's core count and load average at the start
(the machine is shared: compare entries measured at similar loads).
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

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results" / "cli_durations.json"


#: name -> the commands it runs (in order; OUT is a fresh temporary folder).
COMMANDS: dict[str, list[list[str]]] = {
    "paper_quick": [["featherstar", "paper", "--quick", "--out", "OUT"]],
    "paper": [["featherstar", "paper", "--out", "OUT"]],
    "bench_quick": [["featherstar", "bench", "--quick", "--out", "OUT"]],
    "stress_suite": [[sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "stress", "tests/stress"]],
    "stability_map": [[sys.executable, "bench/stability_map.py", "--out", "OUT"]],
    "stability_map_quick": [[sys.executable, "bench/stability_map.py", "--quick", "--out", "OUT"]],
    "guard_margins": [[sys.executable, "bench/guard_margins.py", "--out", "OUT"]],
    # The README's test command as written (CI runs exactly it).
    "test_suite": [[sys.executable, "-m", "pytest", "-q"]],
}


def measure(name: str) -> dict:
    with tempfile.TemporaryDirectory(prefix=f"featherstar-{name}-") as out:
        commands = [[out if part == "OUT" else part for part in command] for command in COMMANDS[name]]
        load = os.getloadavg()[0]
        started = time.perf_counter()
        failed = []
        for command in commands:
            print("$ " + " ".join(command), flush=True)
            if subprocess.run(command, cwd=ROOT).returncode != 0:
                failed.append(" ".join(command))
        wall_s = time.perf_counter() - started
    return {"command": " && ".join(" ".join(c) for c in COMMANDS[name]), "wall_s": wall_s, "failed": failed,
            "cpus": os.cpu_count(), "machine": platform.machine(), "loadavg_1min_at_start": load,
            "measured_unix": time.time()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", action="append", choices=sorted(COMMANDS), help="measure only these (repeatable)")
    parser.add_argument("--out", type=Path, default=RESULTS, help="the JSON to merge into")
    args = parser.parse_args(argv)
    results = json.loads(args.out.read_text()) if args.out.exists() else {}
    for name in args.only or list(COMMANDS):
        results[name] = measure(name)
        print(f"{name}: {results[name]['wall_s']:.1f} s", flush=True)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    return 1 if any(r["failed"] for r in results.values()) else 0


if __name__ == "__main__":
    raise SystemExit(main())
