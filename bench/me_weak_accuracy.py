"""Accuracy of a Model-Exchange-only FMU under weak coupling against strong coupling, at the
same rtol (issue 16, item 3): the hand-written Van der Pol test FMU (tests/cosim/fmu_c/vdp.c,
FMI 2.0 and 3.0, mu = 1, x(0) = (2, 0)) run 10 s by each coupling, max error of x0 and x1 on the
0.01 s grid against solve_ivp at rtol = atol = 1e-13. Writes docs/results/me_weak_accuracy.json.

    python bench/me_weak_accuracy.py            # needs gcc (builds the test FMUs)
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "cosim"))  # the test FMUs' builder (not a package)

from c_fmus import build  # noqa: E402
from featherstar.cosim.scene.data import scene_from_dict  # noqa: E402
from featherstar.cosim.swimmer.run import run_scene  # noqa: E402

T_END_S = 10.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results",
                        help="where the JSON goes (default docs/results)")
    args = parser.parse_args()
    ref = solve_ivp(lambda t, x: [x[1], (1 - x[0] ** 2) * x[1] - x[0]], (0, T_END_S), [2.0, 0.0],
                    rtol=1e-13, atol=1e-13, dense_output=True)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for version in (2, 3):
            fmu = build("vdp", version, Path(folder))
            for rtol in (1e-4, 1e-6, 1e-8):
                row = {"fmi": version, "rtol": rtol}
                for coupling in ("strong", "gauss-seidel", "jacobi"):
                    scene = scene_from_dict({
                        "name": "vdp", "connections": [],
                        "master": {"coupling": coupling, "t_end_s": T_END_S, "step_s": 0.01, "output_interval_s": 0.01,
                                   "rtol": rtol, "atol": rtol * 1e-2},
                        "blocks": {"v": {"kind": "fmu", "fmu": str(fmu)},
                                   "rec": {"kind": "recorder", "signals": ["v.x0", "v.x1"]}},
                    })
                    result = run_scene(scene)
                    exact = ref.sol(result.time)
                    row[coupling] = float(max(np.max(np.abs(result["v.x0"] - exact[0])),
                                              np.max(np.abs(result["v.x1"] - exact[1]))))
                row["gauss_seidel_over_strong"] = row["gauss-seidel"] / row["strong"]
                rows.append(row)
                print(f"FMI {version} rtol {rtol:g}: strong {row['strong']:.2e}  gauss-seidel {row['gauss-seidel']:.2e}  "
                      f"jacobi {row['jacobi']:.2e}  GS/strong {row['gauss_seidel_over_strong']:.2f}")
    args.out.mkdir(parents=True, exist_ok=True)
    out = args.out / "me_weak_accuracy.json"
    out.write_text(json.dumps({"t_end_s": T_END_S, "step_s": 0.01, "rows": rows}, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
