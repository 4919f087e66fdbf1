"""`featherstar optimize SCENE --hardware servo=URL --hardware loadcell=URL`: the study on the bench.

`featherstar.optimizer.cli` adds these options to `optimize` and hands a command with `--hardware` to
`bench_optimize`; the study itself is `featherstar.optimizer.bench.study.run_bench_study`.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ...cosim.scenes import load_scene
from ...hil.hardware import parse_hardware, split_url, with_hardware
from ..errors import OptimizerError
from ..evaluation import MeasurementPlan
from ..loadcell import DEFAULT_NOISE_SD_N, LoadCell
from ..options import count, number
from ..space import SearchSpace
from .objective import DEFAULT_MAX_ATTEMPTS, DEFAULT_REST_S, BenchObjective
from .discrepancy import DEFAULT_NOISE_FLOOR_TR
from .run import BenchFault
from .sim_prior import SimPrior, study_morphology
from .study import BENCH_VALIDATION_PERIODS, BENCH_VALIDATION_REPEATS, PRIOR_USES, run_bench_study

# The hardware loop runs at 250 Hz (hil.hardware.with_hardware's step): one load-cell
# sample per step, read as recorded.
BENCH_SAMPLE_RATE_HZ = 250.0


def add_bench_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group(
        "on the bench", "with --hardware servo=URL --hardware loadcell=URL every evaluation runs the stroke on the "
        "devices in real time (see docs/bench-loop.md)")
    group.add_argument("--hardware", action="append", default=[], metavar="SLOT=URL",
                       help="servo=URL and loadcell=URL (both), as for `featherstar run --hardware`; tip: add "
                            "&reconnect_s=3 so a brief stall discards one run instead of pausing the study")
    group.add_argument("--rest-s", type=number(at_least=0.0), default=DEFAULT_REST_S, metavar="S",
                       help="the feather rests this long at the servo's safe position before every run, "
                            "counted from the previous run's end (the load cell tares at the rest's end: a "
                            "feather still ringing then offsets the whole run; default %(default)s)")
    group.add_argument("--settle-periods", type=count(0), default=3, help="periods run before measuring (default 3)")
    group.add_argument("--periods", type=count(1), default=5, help="measured periods per evaluation (default 5)")
    group.add_argument("--max-attempts", type=count(1), default=DEFAULT_MAX_ATTEMPTS, metavar="N",
                       help="runs of one evaluation discarded in a row before the study pauses (default %(default)s)")
    group.add_argument("--validation-repeats", type=count(1), default=BENCH_VALIDATION_REPEATS, metavar="N",
                       help="validation sets of the optimum and the baseline (paper: 10)")
    group.add_argument("--validation-periods", type=count(1), default=BENCH_VALIDATION_PERIODS, metavar="N",
                       help="periods per validation set (paper: 5)")
    group.add_argument("--prior", type=Path, default=None, metavar="DIR",
                       help="a simulated `featherstar optimize` study of the same feather: its best strokes are "
                            "the bench study's initial points (see --prior-use)")
    group.add_argument("--prior-use", choices=PRIOR_USES, default="seed",
                       help="how the bench study uses --prior: seed = its best strokes are the initial design "
                            "(default); discrepancy = the study's model is that study's simulation plus a learned "
                            "discrepancy (each bench stroke is simulated too; docs/bench-loop.md)")
    group.add_argument("--noise-floor-tr", type=number(above=0.0), default=None, metavar="SD",
                       help="with --prior-use discrepancy: the bench's repeatability, the sd of one stroke's TR "
                            f"measured after different strokes; the least noise the discrepancy may assume "
                            f"(default {DEFAULT_NOISE_FLOOR_TR:g}; docs/bench-loop.md)")


def check_bench_arguments(args: argparse.Namespace) -> None:
    """One clear line for options that make no sense on (or off) the bench."""
    if not args.hardware:
        for flag, given in (("--prior", args.prior is not None), ("--rest-s", args.rest_s != DEFAULT_REST_S),
                            ("--prior-use", args.prior_use != "seed"),
                            ("--noise-floor-tr", args.noise_floor_tr is not None),
                            ("--max-attempts", args.max_attempts != DEFAULT_MAX_ATTEMPTS)):
            if given:
                raise OptimizerError(f"{flag} applies to a study on the bench (--hardware servo=URL --hardware "
                                     "loadcell=URL)")
        return
    if args.noise_floor_tr is not None and args.prior_use != "discrepancy":
        raise OptimizerError("--noise-floor-tr applies to --prior-use discrepancy (the discrepancy's noise floor)")
    if args.prior_use != "seed" and args.prior is None:
        raise OptimizerError(f"--prior-use {args.prior_use} needs --prior DIR (a simulated study of the same feather)")
    if args.scheduler or args.batch_size != 1 or args.workers not in (None, 1):
        raise OptimizerError("--hardware: one bench runs one stroke at a time; --scheduler, --workers and "
                             "--batch-size do not apply")
    if args.noise_N != DEFAULT_NOISE_SD_N:
        raise OptimizerError("--noise-N does not apply with --hardware: the bench's load cell has its own noise")
    if not args.rest_s >= 0:
        raise OptimizerError(f"--rest-s {args.rest_s} must be >= 0")
    if args.settle_periods < 0 or args.periods < 1:
        raise OptimizerError(f"--settle-periods {args.settle_periods} must be >= 0 and --periods {args.periods} >= 1")


def bench_optimize(args: argparse.Namespace, space: SearchSpace, overrides: dict, compare: tuple) -> int:
    hardware = parse_hardware(args.hardware)
    for slot in ("servo", "loadcell"):
        if slot not in hardware:
            raise OptimizerError(f"--hardware {slot}=URL is missing: a bench study needs both the servo and the load cell")
        split_url(slot, hardware[slot])   # bad block options stop here, not after the first rest
    with_hardware(load_scene(args.scene), hardware)   # a scene without a servo to replace, too
    bench = BenchObjective(args.scene, hardware, overrides, settle_periods=args.settle_periods, rest_s=args.rest_s)
    plan = MeasurementPlan(load_cell=LoadCell(noise_sd_N=0.0, sample_rate_hz=BENCH_SAMPLE_RATE_HZ),
                           settle_periods=args.settle_periods, periods=args.periods, seed=args.seed)
    maximize = args.objective == "max"
    prior = None
    if args.prior is not None:
        prior = SimPrior.load(args.prior, feather=study_morphology(args.scene, overrides), space=space,
                              maximize=maximize)
    print(f"optimizing {args.scene} ON THE BENCH ({args.objective} TR, {args.iterations} iterations, "
          f"{args.settle_periods}+{args.periods} periods of {space.period_s:g} s each, rest {args.rest_s:g} s"
          f"{f', prior {args.prior} ({args.prior_use})' if prior else ''}) → {args.out}/evaluations.jsonl", flush=True)
    try:
        summary = run_bench_study(
            bench, space, args.out, plan=plan, iterations=args.iterations, maximize=maximize, resume=args.resume,
            max_attempts=args.max_attempts, validation_repeats=args.validation_repeats,
            validation_periods=args.validation_periods, prior=prior, prior_use=args.prior_use,
            noise_floor_sd=args.noise_floor_tr, label=args.label or args.scene,
            compare=compare, on_record=_print_record,
        )
    except BenchFault as fault:
        print(f"featherstar: error: {fault}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"interrupted: every finished evaluation is logged under {args.out}; rerun with --resume to continue",
              file=sys.stderr)
        return 130
    print(
        f"best, measured ({summary['objective']}): {json.dumps(summary['best_params'])}\n"
        f"  TR = {summary['thrust_ratio']:.3f} ± {summary['thrust_ratio_sd']:.3f} as validated "
        f"(the model had estimated {summary['estimated_thrust_ratio']:.3f}), "
        f"mean thrust {summary['mean_thrust_N'] * 1e3:.2f} mN\n"
        f"  baseline TR = {summary['baseline_thrust_ratio']:.3f} ± {summary['baseline_thrust_ratio_sd']:.3f}\n"
        f"  {summary['discarded_runs']} runs discarded and repeated, {summary['faults']} pauses\n"
        f"wrote {args.out}/summary.json, fig6_progress.png, fig8_validation.png"
    )
    for warning in summary["warnings"]:
        print(f"featherstar: WARNING: {warning}", file=sys.stderr)
    return 0


def _print_record(record: dict) -> None:
    kind = record["kind"]
    if kind == "evaluation":
        print(f"  #{record['index'] + 1:3d}  TR {record['thrust_ratio']:.3f}  T̄ {record['mean_thrust_N'] * 1e3:7.2f} mN  "
              f"bench {record['bench_wall_s']:.1f} s{'  (from prior)' if record['from_prior'] else ''}", flush=True)
    elif kind == "discarded":
        what = f"#{record['index'] + 1}" if "index" in record else f"validation of the {record['validation']}"
        print(f"  {what} discarded, repeating: {'; '.join(record['reasons'])}", flush=True)
    elif kind == "validation":
        print(f"  validated {record['controller']}: TR {record['thrust_ratio']:.3f} ± {record['thrust_ratio_sd']:.3f}",
              flush=True)
