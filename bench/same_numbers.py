"""The test bed's TR and mean thrust under every coupling, to the last digit.

A refactor that only moves code must not change a number: run this before and after, and
compare the JSON (`python bench/same_numbers.py --out a.json`, then `diff a.json b.json`).
Each coupling runs the shipped test bed on its embedded defaults (the chordwise feather, 6 periods);
the values are written with `repr`, so equal files mean equal floats.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from featherstar.cosim import run_scene

COUPLINGS = ("strong", "jacobi", "gauss-seidel")


def measure(periods: int = 6) -> dict[str, dict[str, str]]:
    """{coupling: {"thrust_ratio": repr, "mean_thrust_N": repr}} for the test bed."""
    out = {}
    for coupling in COUPLINGS:
        result = run_scene("testbed", {"master.coupling": coupling, "master.periods": periods}, progress=False)
        out[coupling] = {key: repr(float(result.summary[key])) for key in ("thrust_ratio", "mean_thrust_N")}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, metavar="DIR", help="write same_numbers.json here (default: print only)")
    args = parser.parse_args(argv)
    numbers = measure()
    text = json.dumps(numbers, indent=2, sort_keys=True)
    print(text)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "same_numbers.json").write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
