"""The feathers with wake memory (issue 26, item 1): TR and mean thrust through the test bed under
each wake law, next to the quasi-steady model, and what the wake costs.

Cases: the plain feather under the paper's symmetric stroke and under the slow-return stroke the
optimizer finds for it in the quasi-steady model (up 0.68 s, hold 0.48 s, down 0.32 s, hold
0.02 s: docs/model.md), the chordwise and spanwise feathers under the symmetric stroke. Cost: the
RHS's CasADi instructions and compiled µs per evaluation (chordwise, N = 10), and the test bed's
run time (best of 3, FMU already built).

Writes <out>/wake_feathers.json (default docs/results).

    python bench/wake_feathers.py [--out DIR]      (~6 min alone on 2 cores, FMU builds included)
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from featherstar.cosim import run_scene  # noqa: E402
from featherstar.fmu_src.feather import feather_model  # noqa: E402
from featherstar.fmu_src.fluid import WAKE_LAWS  # noqa: E402

from bench._rhs_cost import rhs_ns_per_evaluation  # noqa: E402

SLOW_RETURN = {"controller.t_up_s": 0.68, "controller.t_hold_up_s": 0.48, "controller.t_down_s": 0.32,
               "controller.t_hold_down_s": 0.02}
CASES = {
    "plain, symmetric": {"feather.morphology": "plain"},
    "plain, slow return": {"feather.morphology": "plain", **SLOW_RETURN},
    "chordwise, symmetric": {},
    "spanwise, symmetric": {"feather.morphology": "spanwise"},
}


def testbed(overrides: dict, repeats: int) -> dict:
    walls = []
    for _ in range(repeats):
        started = time.perf_counter()
        result = run_scene("testbed", overrides)
        walls.append(time.perf_counter() - started)
    return {"thrust_ratio": float(result.summary["thrust_ratio"]), "mean_thrust_N": float(result.summary["mean_thrust_N"]),
            "wall_s_best": min(walls[1:] or walls)}


def cost(wake: str) -> dict:
    model = feather_model("chordwise", 10, wake=wake)
    x = np.random.default_rng(0).normal(0.0, 0.3, model.x.numel())
    rhs = rhs_ns_per_evaluation(model.function(), x, [0.3, 1.0, 5.0, 0.0], model.parameter_vector(), repeats=5)
    return {"states": model.x.numel(), "instructions": model.function().n_instructions(),
            "rhs_us": rhs["ns_median"] / 1e3}


def run(out: Path) -> dict:
    started = time.perf_counter()
    result: dict = {"laws": {}}
    for wake in ("none", *WAKE_LAWS):
        row = {"cost_chordwise_n10": cost(wake),
               "cases": {case: testbed({**overrides, "feather.wake": wake}, repeats=3) for case, overrides in CASES.items()}}
        result["laws"][wake] = row
        print(wake, row["cost_chordwise_n10"], {c: round(v["thrust_ratio"], 4) for c, v in row["cases"].items()},
              flush=True)
    result["seconds"] = time.perf_counter() - started
    out.mkdir(parents=True, exist_ok=True)
    (out / "wake_feathers.json").write_text(json.dumps(result, indent=1))
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results", help="where the JSON goes")
    run(parser.parse_args(argv).out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
