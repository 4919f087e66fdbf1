"""The benchmark dashboard: every benchmark in bench/, one JSON and one markdown report.

The same as `featherstar bench [--quick] [--out DIR]` (library code: bench/dashboard/, installed as featherstar.dashboard). Runs
every other script in this folder (--quick passed through, reduced where needed to stay under
5 minutes on the 2-core machine), adds its own side-by-side measurements (the master against a
monolithic CasADi model and against scipy solve_ivp of the same equations; cost growth with N
and with the simulated duration) and writes <out>/dashboard.json and <out>/dashboard.md with
plots (default out: bench/results).

    python bench/dashboard.py [--quick] [--out DIR] [--jobs 2] [--timeout S]
"""
from __future__ import annotations

import sys

from featherstar.dashboard import main

if __name__ == "__main__":
    sys.exit(main())
