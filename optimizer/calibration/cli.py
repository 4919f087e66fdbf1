"""`featherstar calibrate RUN... --scene SCENE`: fit feather coefficients to recorded load-cell runs.

Writes DIR/calibration.json (the parameter set, each coefficient with its sd and range, fit
quality), DIR/set.txt (the same as `--set` arguments for run, optimize and sweep),
DIR/feather-parameters.toml (the feather block's `parameters` line for a scene file) and
DIR/fit.png (measured and fitted thrust per run). The method: featherstar.optimizer.calibration.fit.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from ...fmu_src.catalog import build_options
from ..errors import OptimizerError
from ..log import dumps
from ..options import command, number, one_line_errors, out_dir
from ..postprocess import optional
from .fit import BIN_S, DEFAULT_COEFFICIENTS, Calibration, calibrate, feather_block
from .recordings import read_recording


def _fit(text: str) -> tuple[str, tuple[float, float] | None]:
    name, sep, pair = text.partition("=")
    if not sep:
        return name.strip(), None
    low, comma, high = pair.partition(",")
    try:
        if not comma:
            raise ValueError
        return name.strip(), (float(low), float(high))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--fit wants NAME or NAME=LOW,HIGH (e.g. drag_coeff=0.5,3), got {text!r}") from None


def register_calibrate(subparsers: argparse._SubParsersAction, override_type) -> None:
    cal = subparsers.add_parser(
        "calibrate", help="fit feather coefficients (drag, added mass, hinge stiffness) to recorded load-cell runs",
        description="Fit coefficients of a scene's feather to recorded runs: `featherstar run --hardware --out DIR` "
                    "directories, or CSVs with time, root angle and thrust columns. The runs must repeat one stroke, "
                    "from rest. The simulated feather's root follows the recorded angle; the fit matches the thrust "
                    f"averaged over {BIN_S * 1e3:g} ms bins over the first window (docs/bench-loop.md says why).")
    one_line_errors(cal)
    cal.add_argument("runs", nargs="+", type=Path, metavar="RUN", help="run directory or CSV (repeatable)")
    cal.add_argument("--scene", default="testbed", help="scene whose feather block is calibrated (default testbed)")
    cal.add_argument("--set", dest="overrides", metavar="KEY=VALUE", type=override_type, action="extend", nargs="+",
                     default=[], help="scene overrides, one or more per --set, e.g. feather.morphology=spanwise "
                     "(the feather the bench has)")
    cal.add_argument("--fit", type=_fit, action="append", default=[], metavar="NAME[=LOW,HIGH]",
                     help=f"coefficient to fit, within its physical range or a narrower one (default: "
                          f"{', '.join(DEFAULT_COEFFICIENTS)}, those the feather has)")
    cal.add_argument("--window-s", type=number(above=0.0), default=None, metavar="S",
                     help="fit the first S seconds of each run (default: one stroke period, from summary.json)")
    cal.add_argument("--time-column", default=None)
    cal.add_argument("--angle-column", default=None)
    cal.add_argument("--thrust-column", default=None)
    cal.add_argument("--out", type=out_dir, default="runs/calibration", help="output directory")
    cal.set_defaults(func=command("featherstar calibrate", _calibrate_command))


def _calibrate_command(args: argparse.Namespace) -> int:
    recordings = [read_recording(path, time_column=args.time_column, angle_column=args.angle_column,
                                 thrust_column=args.thrust_column) for path in args.runs]
    overrides = dict(args.overrides)
    stray = [k for k in overrides if not k.startswith("feather.")]
    if stray:
        raise OptimizerError(f"--set {stray[0]}: calibrate simulates the feather alone; only feather.* overrides apply")
    fit = dict(args.fit) or None
    print(f"calibrating the feather of {args.scene} on {len(recordings)} runs ...", flush=True)
    result = calibrate(recordings, args.scene, overrides, fit, window_s=args.window_s)
    paths = write_calibration(result, args.out, runs=[r.source for r in recordings], scene=args.scene,
                              overrides=overrides)
    # The figure is optional post-processing: the calibration is already on disk.
    if optional("fit.png", _fit_figure, result, [r.source for r in recordings], args.out / "fit.png") is not None:
        paths.append(args.out / "fit.png")
    for c in result.coefficients:
        print(f"  {c.name:28s} {result.values[c.name]:.4g} ± {result.sd[c.name]:.2g} {c.unit}  "
              f"(range {c.low:g}..{c.high:g}, start {c.start:g})")
    for name, value in result.fixed.items():
        print(f"  {name:28s} {value:g} (fixed: the fitted drag_coeff replaces the per-point oscillatory drag)")
    print(f"  fit: rms residual {result.rms_residual_N * 1e3:.2f} mN, R² {result.r_squared:.3f}, "
          f"{result.evaluations} simulations, {result.wall_s:.0f} s")
    print(f"use it: {set_arguments(result)}")
    print(f"wrote {', '.join(str(p) for p in paths)}")
    return 0


def set_arguments(result: Calibration) -> str:
    return " ".join(f"--set {k}={v:.6g}" for k, v in result.parameter_set().items())


def write_calibration(result: Calibration, out: Path, *, runs: list[str], scene: str, overrides: dict) -> list[Path]:
    """calibration.json, set.txt and feather-parameters.toml (the figure is drawn separately)."""
    out.mkdir(parents=True, exist_ok=True)
    report = {**result.as_dict(), "scene": scene, "overrides": overrides, "runs": runs, "window_s": result.window_s}
    paths = [out / "calibration.json", out / "set.txt", out / "feather-parameters.toml"]
    paths[0].write_text(json.dumps(json.loads(dumps(report)), indent=2) + "\n")
    paths[1].write_text(set_arguments(result) + "\n")
    # The scene's own feather parameters, the feather.* overrides, then the calibrated ones.
    merged = {**feather_block(scene).get("parameters", {}),
              **{k.split(".", 1)[1]: v for k, v in overrides.items() if k.startswith("feather.")
                 and k.split(".", 1)[1] not in build_options("feather")},
              **{k.split(".", 1)[1]: v for k, v in result.parameter_set().items()}}
    inline = ", ".join(f"{k} = {v:.6g}" if isinstance(v, (int, float)) else f'{k} = "{v}"' for k, v in merged.items())
    paths[2].write_text(f"# calibrated feather of scene '{scene}' ({', '.join(Path(r).name for r in runs)}):\n"
                        "# replace the parameters line of the scene's [blocks.feather] table with\n"
                        f"parameters = {{ {inline} }}\n")
    return paths


def _fit_figure(result: Calibration, runs: list[str], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ...cosim.plotstyle import save_figure

    fig, ax = plt.subplots(figsize=(7, 3.2))
    for k, run in enumerate(runs):
        ax.plot(result.bin_times_s, result.measured_N[k] * 1e3, ".", ms=3, color=f"C{k}", label=f"measured {Path(run).name}")
    ax.plot(result.bin_times_s, result.simulated_N[0] * 1e3, "-", color="k", lw=1.2, label="calibrated simulation")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"thrust, {BIN_S * 1e3:g} ms means (mN)")
    ax.set_title(f"calibration: rms residual {result.rms_residual_N * 1e3:.1f} mN, R² {result.r_squared:.3f}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)
