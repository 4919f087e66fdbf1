"""`featherstar optimize | sweep | codesign | paper`: thin wrappers over the library.

`register(subparsers)` is called by the `featherstar` entry point (featherstar.app); `main()` runs the same
commands standalone (`python -m featherstar.optimizer.cli ...`). SCENE is a cosim scene name or path, or
`synthetic:MORPHOLOGY` for the analytic stand-in (featherstar.optimizer.synthetic), which needs no FMU.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Sequence

from ..fmu_src.errors import FeatherstarError
from .bayes import DEFAULT_INITIAL_POINTS, DEFAULT_ITERATIONS
from .bench.cli import add_bench_options, bench_optimize, check_bench_arguments
from .calibration.cli import register_calibrate
from .codesign import MORPHOLOGY_VARIABLES, codesign
from .errors import OptimizerError
from .evaluation import MeasurementPlan
from .executor import Executor, make_executor
from .figures import sweep_figure
from .loadcell import DEFAULT_NOISE_SD_N, LoadCell
from .objective import Objective, SceneObjective, WithOverrides
from .options import command, count, number, one_line_errors, out_dir
from .space import STROKE_VARIABLES, ServoLimits, stroke_space
from .postprocess import optional
from .study import SUMMARY_KEYS, baseline_outside_box, run_study
from .sweep import FAMILIES, format_table, normalized_thrust_note, run_sweep, write_csv
from .synthetic import SyntheticFeather

_SYNTHETIC_PREFIX = "synthetic:"


# The optimizer sets each evaluation's run length and metric window from its measurement plan.
_PLAN_KEYS = ("master.periods", "master.t_end_s", "metrics.settle_periods", "metrics.period_s")


def make_objective(scene: str, overrides: dict[str, str | float]) -> Objective:
    fixed = [key for key in overrides if key in _PLAN_KEYS]
    if fixed:
        raise OptimizerError(f"--set {fixed[0]}: refused, the optimizer sets the run length and "
                             "the settling itself for every evaluation (its measurement plan: "
                             "settling + measured periods), so this override would be ignored")
    if scene.startswith(_SYNTHETIC_PREFIX):
        return WithOverrides(SyntheticFeather(morphology=scene[len(_SYNTHETIC_PREFIX):]), overrides)
    return SceneObjective(scene, overrides)


def _override(text: str) -> tuple[str, str | float]:
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"--set wants KEY=VALUE, got {text!r}")
    try:
        return key.strip(), float(value)
    except ValueError:
        return key.strip(), value.strip()


def _bounds(text: str) -> tuple[str, tuple[float, float]]:
    name, sep, pair = text.partition("=")
    low, comma, high = pair.partition(",")
    try:
        if not (sep and comma):
            raise ValueError
        return name.strip(), (float(low), float(high))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--bounds wants NAME=LOW,HIGH (e.g. {STROKE_VARIABLES[0]}=-0.3,0.3), got {text!r}") from None


def _common(parser: argparse.ArgumentParser, *, default_noise_N: float) -> None:
    parser.add_argument("scene", metavar="SCENE", help="scene name or path, or synthetic:plain|chordwise|spanwise")
    parser.add_argument("--set", dest="overrides", metavar="KEY=VALUE", type=_override, action="extend", nargs="+",
                        default=[], help="scene overrides, one or more per --set, repeatable (e.g. "
                        "feather.width_ratio=7.5)")
    parser.add_argument("--noise-N", type=number(at_least=0.0), default=default_noise_N, metavar="SD",
                        help=f"load-cell noise sd in newtons (default {default_noise_N:g}; 0 = ideal sensor)")
    parser.add_argument("--seed", type=count(0), default=0, help="seed of the noise and of the optimizer")
    parser.add_argument("--amplitude-deg", type=number(above=0.0), default=60.0, help="stroke amplitude in degrees, peak to peak (60: the root swings between -30 and +30)")


def _where(parser: argparse.ArgumentParser, *, batches: bool) -> None:
    """Where the experiments run: --scheduler, --workers (and --batch-size for the optimizer)."""
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="run on this Dask scheduler (e.g. tcp://host:8786) instead of local processes")
    if batches:
        parser.add_argument("--batch-size", type=count(1), default=1, metavar="K",
                            help="evaluations asked (constant liar) and run at once (default 1)")
        parser.add_argument("--workers", type=count(1), default=None, metavar="N",
                            help="local processes (default: the batch size, at most all cores)")
    else:
        parser.add_argument("--workers", type=count(1), default=None, metavar="N", help="local processes (default: all cores)")


def _executor(args: argparse.Namespace, *, default_workers: int | None = None) -> Executor:
    """Open the executor the arguments ask for; on a cluster, say where its dashboard is."""
    executor = make_executor(args.scheduler, default_workers if args.workers is None else args.workers)
    if args.scheduler:
        print(executor.describe(), file=sys.stderr, flush=True)
    return executor


def _batch_workers(args: argparse.Namespace) -> int:
    return min(args.batch_size, os.cpu_count() or 1)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the optimize, sweep, codesign, calibrate and paper subcommands; each sets `func`."""
    opt = one_line_errors(subparsers.add_parser("optimize", help="Bayesian optimization of the stroke (paper Sec. II-D)"))
    _common(opt, default_noise_N=DEFAULT_NOISE_SD_N)
    opt.add_argument("--objective", choices=("max", "min"), default="max", help="best (max TR) or worst (min TR)")
    opt.add_argument("--iterations", type=count(DEFAULT_INITIAL_POINTS, "the optimizer's random initial points"),
                     default=DEFAULT_ITERATIONS)
    opt.add_argument("--period", type=number(above=0.0), default=1.5, dest="period_s", help="stroke period in s (paper: 1.5, 3)")
    opt.add_argument("--bounds", type=_bounds, action="append", default=[], metavar="NAME=LOW,HIGH",
                     help=f"narrow a variable's servo-derived bounds; variables: {', '.join(STROKE_VARIABLES)}")
    opt.add_argument("--servo-rate", type=number(above=0.0), default=ServoLimits().max_rate_rad_s, metavar="RAD_S",
                     help="servo no-load speed that bounds the ramps")
    opt.add_argument("--out", type=out_dir, default="runs/optimize", help="output directory")
    opt.add_argument("--resume", action="store_true", help="continue the run logged in --out")
    opt.add_argument("--label", default=None, help="morphology label in Fig. 8 (default: the scene)")
    opt.add_argument("--compare", type=Path, nargs="*", default=[], metavar="DIR",
                     help="other optimize output directories to draw in the same Fig. 8")
    _where(opt, batches=True)
    add_bench_options(opt)
    opt.set_defaults(func=command("featherstar optimize", _optimize_command))

    sweep = one_line_errors(subparsers.add_parser("sweep", help="morphology × controller grid sweep (paper Fig. 3)"))
    _common(sweep, default_noise_N=0.0)
    sweep.add_argument("--family", choices=(*FAMILIES, "both"), default="both")
    sweep.add_argument("--settle-periods", type=count(0), default=2, help="periods run before measuring")
    sweep.add_argument("--periods", type=count(1), default=3, help="measured periods per run")
    _where(sweep, batches=False)
    sweep.add_argument("--no-progress", action="store_true")
    sweep.add_argument("--out", type=out_dir, default="runs/sweep", help="output directory (runs.jsonl: every run)")
    sweep.add_argument("--resume", action="store_true", help="continue the sweep logged in --out: only missing runs")
    sweep.set_defaults(func=command("featherstar sweep", _sweep_command))

    co = one_line_errors(subparsers.add_parser("codesign", help="joint morphology + stroke search vs the two-stage approach"))
    _common(co, default_noise_N=DEFAULT_NOISE_SD_N)
    co.add_argument("--family", choices=sorted(MORPHOLOGY_VARIABLES), default="chordwise")
    budget = count(DEFAULT_INITIAL_POINTS + 2, f"stage 1 needs 2 experiments, the stroke search {DEFAULT_INITIAL_POINTS}")
    co.add_argument("--budget", type=budget, default=DEFAULT_ITERATIONS, help="experiments per approach")
    co.add_argument("--period", type=number(above=0.0), default=1.5, dest="period_s")
    co.add_argument("--out", type=out_dir, default="runs/codesign")
    co.add_argument("--resume", action="store_true")
    _where(co, batches=True)
    co.set_defaults(func=command("featherstar codesign", _codesign_command))

    register_calibrate(subparsers, _override)

    paper = subparsers.add_parser(
        "paper", help="rerun the paper's experiments; markdown report with Figs. 3, 5-9 and a claims table",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Rerun the paper's experiments in simulation and write DIR/report.md with\n"
            "  Fig. 3  thrust ratio vs width ratio (chordwise) and length ratio (spanwise): the sweep\n"
            "  Fig. 5  plain, chordwise and spanwise feathers under the symmetric stroke\n"
            "  Fig. 6  optimizer progress, chordwise WR 7.5 and spanwise LR 2\n"
            "  Fig. 7  optimized strokes for the tested WR and LR at periods 1.5 s and 3 s\n"
            "  Fig. 8  TR and mean thrust with the best, baseline and worst controllers\n"
            "  Fig. 9  robot displacement and speed with those controllers\n"
            "and a table of every number the paper reports beside the simulated value, whether it\n"
            "agrees and, where the model cannot reproduce it, why. Every number is also in DIR/paper.json."
        ),
        epilog=(
            "--quick: 4 sweep geometries per family, 2 controllers, 8 optimizer iterations, 3\n"
            "validation sets; without it the paper's budgets (the whole sweep grid, 30 iterations,\n"
            "10 sets of 5 periods). Both reports state their run time and resolution; README.md gives\n"
            "both as measured. Example: docs/paper-report/report.md"
        ),
    )
    one_line_errors(paper)
    paper.add_argument("--quick", action="store_true", help="reduced resolution and budgets (see below)")
    paper.add_argument("--out", type=out_dir, default="runs/paper", metavar="DIR", help="output directory (default runs/paper)")
    _where(paper, batches=False)
    paper.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    paper.add_argument("--resume", action="store_true",
                       help="continue the report in --out: only the experiments its tasks.jsonl lacks")
    paper.set_defaults(func=command("featherstar paper", _paper_command))


def _plan(args: argparse.Namespace, **kwargs: int) -> MeasurementPlan:
    return MeasurementPlan(load_cell=LoadCell(noise_sd_N=args.noise_N), seed=args.seed, **kwargs)


def _optimize_command(args: argparse.Namespace) -> int:
    overrides = dict(args.overrides)
    space = stroke_space(args.period_s, amplitude_deg=args.amplitude_deg,
                         servo=ServoLimits(max_rate_rad_s=args.servo_rate), bounds=dict(args.bounds))
    compare = [_summary(directory) for directory in args.compare]
    check_bench_arguments(args)
    if args.hardware:
        if args.scene.startswith(_SYNTHETIC_PREFIX):
            raise OptimizerError(f"--hardware: {args.scene} is an analytic stand-in; give the scene the bench runs")
        make_objective(args.scene, overrides)   # the same refusals as a simulated study (--set master.*)
        return bench_optimize(args, space, overrides, tuple(compare))
    objective = make_objective(args.scene, overrides)
    print(f"optimizing {args.scene} ({args.objective} TR, {args.iterations} iterations) → {args.out}/evaluations.jsonl")
    outside = baseline_outside_box(space)
    if outside:
        print(f"note: {outside}")
    try:
        with _executor(args, default_workers=_batch_workers(args)) as executor:
            summary = run_study(
                objective, space, args.out, maximize=args.objective == "max",
                iterations=args.iterations, plan=_plan(args), resume=args.resume,
                context={"scene": args.scene, "overrides": overrides}, label=args.label or args.scene,
                compare=tuple(compare), on_evaluation=_print_evaluation, batch_size=args.batch_size,
                executor=executor,
            )
    except KeyboardInterrupt:
        return _interrupted(args.out)
    print(
        f"best ({summary['objective']}): {json.dumps(summary['best_params'])}\n"
        f"  TR = {summary['thrust_ratio']:.3f} ± {summary['thrust_ratio_sd']:.3f} "
        f"(estimated {summary['estimated_thrust_ratio']:.3f}), mean thrust {summary['mean_thrust_N'] * 1e3:.2f} mN\n"
        f"  baseline TR = {summary['baseline_thrust_ratio']:.3f} ± {summary['baseline_thrust_ratio_sd']:.3f}\n"
        f"wrote {args.out}/summary.json, fig6_progress.png, fig8_validation.png"
    )
    sign = 1 if summary["objective"] == "max" else -1
    if summary["baseline_outside_search_box"] and sign * (summary["thrust_ratio"] - summary["baseline_thrust_ratio"]) < 0:
        print(f"the study ended {'below' if sign > 0 else 'above'} the baseline, and "
              f"{summary['baseline_outside_search_box']}")
    return 0


def _summary(directory: Path) -> dict:
    """An earlier study's summary.json, for --compare; refused with one line if it is not one."""
    path = directory / "summary.json"
    try:
        summary = json.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise OptimizerError(f"--compare {directory}: no summary.json there") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise OptimizerError(f"--compare {directory}: summary.json is unreadable ({exc})") from None
    missing = [k for k in SUMMARY_KEYS if not isinstance(summary, dict) or k not in summary]
    if missing:
        raise OptimizerError(f"--compare {directory}: summary.json is not a study's summary (no {missing[0]!r})")
    return summary


def _interrupted(out: Path) -> int:
    print(f"interrupted: every finished evaluation is logged under {out}; rerun with --resume to continue",
          file=sys.stderr)
    return 130


def _print_evaluation(record: dict) -> None:
    print(f"  #{record['index'] + 1:3d}  TR {record['thrust_ratio']:.3f}  T̄ {record['mean_thrust_N'] * 1e3:7.2f} mN  "
          f"sim {record['sim_wall_s']:.2f} s", flush=True)


def _sweep_command(args: argparse.Namespace) -> int:
    families = FAMILIES if args.family == "both" else (args.family,)
    try:
        with _executor(args) as executor:
            result = run_sweep(
                make_objective(args.scene, dict(args.overrides)), families,
                plan=_plan(args, settle_periods=args.settle_periods, periods=args.periods),
                amplitude_deg=args.amplitude_deg, executor=executor, log_path=args.out / "runs.jsonl",
                resume=args.resume, context={"scene": args.scene, "overrides": dict(args.overrides)},
                progress=not args.no_progress,
            )
    except KeyboardInterrupt:
        return _interrupted(args.out)
    write_csv(result.runs, args.out / "runs.csv")
    write_csv(result.table, args.out / "table.csv")
    timing = {"wall_s": result.wall_s, "simulation_s": result.simulation_s, "workers": result.workers,
              "runs": len(result.runs), "resumed_runs": result.resumed_runs,
              "failed_runs": sum(1 for r in result.runs if r["error"])}
    note = normalized_thrust_note(result.runs, result.table)
    if note:
        timing["normalized_thrust_undefined"] = note
    (args.out / "summary.json").write_text(json.dumps(timing, indent=2) + "\n")
    optional("fig3_sweep.png", sweep_figure, result.table, ["thrust_ratio", "normalized_thrust"],
             args.out / "fig3_sweep.png", note=note)
    print(format_table(result.table))
    if note:
        print(f"normalized thrust (max T̄/T̄ref) undefined for every geometry, column NaN and not drawn: {note}")
    print(f"{len(result.runs)} runs in {result.wall_s:.1f} s; wrote {args.out}/runs.csv, table.csv, fig3_sweep.png")
    return 0


def _codesign_command(args: argparse.Namespace) -> int:
    try:
        with _executor(args, default_workers=_batch_workers(args)) as executor:
            report = codesign(
                make_objective(args.scene, dict(args.overrides)), args.family, args.out, period_s=args.period_s,
                budget=args.budget, plan=_plan(args), amplitude_deg=args.amplitude_deg, resume=args.resume,
                context={"scene": args.scene, "overrides": dict(args.overrides)}, batch_size=args.batch_size,
                executor=executor,
            )
    except KeyboardInterrupt:
        return _interrupted(args.out)
    for approach in ("joint", "two_stage"):
        r = report[approach]
        print(f"{approach:>9}: ratio {r['ratio']:.2f}  TR {r['thrust_ratio']:.3f} ± {r['thrust_ratio_sd']:.3f}")
    print(f"wrote {args.out}/codesign.json")
    return 0


def _paper_command(args: argparse.Namespace) -> int:
    import dataclasses

    from .paper.paper import FULL, QUICK, generate_report

    resolution = dataclasses.replace(QUICK if args.quick else FULL, workers=args.workers)
    with _executor(args, default_workers=resolution.workers or os.cpu_count() or 1) as executor:
        path = generate_report(args.out, quick=args.quick, progress=not args.no_progress, resolution=resolution,
                               executor=executor, resume=args.resume)
    print(f"wrote {path} (figures and paper.json beside it)")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="featherstar")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except FeatherstarError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
