"""`featherstar run` and `featherstar scenes`: run a scene (optionally with hardware blocks swapped
in, featherstar.hil.hardware) and list the shipped scenes. Registered by featherstar.app."""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Sequence

from .terminal import EXIT_FOR_SIGNAL, exit_status, one_line, stop_signals


def _parse_set(items: Sequence[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for item in items or ():
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise argparse.ArgumentTypeError(f"--set '{item}' must read BLOCK.PARAM=VALUE")
        out[key.strip()] = value.strip()
    return out


def _check_out_dir(out: Path) -> None:
    """Refuse an --out that cannot be written before the run, not after it, and clear an earlier
    run's outputs there: a run refused or failed from here on leaves no stale summary behind."""
    from .cosim.errors import SceneError
    from .cosim.out_dir import out_dir_problem
    from .cosim.swimmer.report import clear_outputs

    problem = out_dir_problem(out)
    if problem:
        raise SceneError(f"--out {out}: cannot write there: it {problem}")
    try:
        out.mkdir(parents=True, exist_ok=True)
        clear_outputs(out)
    except OSError as exc:
        raise SceneError(f"--out {out}: cannot write there ({exc.strerror or exc})") from None


def _write(result: object, out: Path, figure: bool) -> dict[str, Path]:
    """The run's outputs; a figure that failed is a warning (the results are written)."""
    from .cosim.errors import StepError
    from .cosim.swimmer.report import write_outputs

    try:
        paths = write_outputs(result, out, figure=figure)
    except OSError as exc:
        raise StepError("master", 0.0, f"cannot write the results to --out {out} "
                        f"({exc.strerror or exc})", cause="a full disk or a folder made read-only "
                        "during the run") from None
    for warning in getattr(result, "summary", {}).get("warnings", []):
        if warning.startswith("figure not written"):
            print(f"featherstar: warning: {warning}; the results are in {out}", file=sys.stderr)
    return paths


def _cmd_run(args: argparse.Namespace) -> int:
    try:
        overrides = _parse_set(args.set)
    except argparse.ArgumentTypeError as exc:
        print(f"featherstar run: {exc}", file=sys.stderr)
        return 2
    outputs = args.record.split(",") if args.record else None
    if args.out:
        _check_out_dir(args.out)
    scene = args.scene
    if args.allow_code:
        from .cosim.scenes import load_scene

        scene = load_scene(args.scene, allow_code=True)
    if args.hardware:
        from .cosim.scenes import load_scene
        from .hil.hardware import check_hardware_overrides, parse_hardware, with_hardware

        # The hardware blocks report every fault themselves (one line, with device and time);
        # pymodbus' own log of the same event would only bury it.
        logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
        scene = with_hardware(load_scene(scene), parse_hardware(args.hardware),
                              allow_unactuated=args.allow_unactuated_loadcell)
        check_hardware_overrides(scene, overrides)
    # With hardware, a signal is honoured between steps, never inside the safe stop, and the
    # outputs are written before the command exits with the signal's status.
    with stop_signals(deferred=bool(args.hardware)) as stop:
        return exit_status(_run_and_report(args, scene, overrides, outputs, stop), stop)


def _run_and_report(args: argparse.Namespace, scene, overrides, outputs, stop) -> int:
    from .cosim.errors import StepError
    from .cosim.swimmer.report import summary_table
    from .cosim.swimmer.run import run_scene
    runner = run_scene
    if args.hardware:   # streamed, or device-timed when the URLs say clock=device
        from .hil.timed_run import run_bench_scene as runner
    try:
        result = runner(scene, overrides, outputs=outputs, progress=not args.quiet,
                           strict_window=True)
    except StepError as exc:
        where = ""
        if exc.partial is not None and args.out:
            try:
                paths = _write(exc.partial, args.out, figure=not args.no_figure)
                where = f"; partial results up to t={exc.t_s:.6g} s in {paths['results'].parent}"
            except StepError as lost:
                where = f"; partial results lost: {one_line(lost)}"
        elif exc.partial is not None:
            where = "; nothing kept (no --out)"
        unsafe = [name for name, ok in ((exc.partial.summary if exc.partial else {})
                                        .get("safe_position_confirmed") or {}).items() if not ok]
        if unsafe:
            where += f"; WARNING: {', '.join(unsafe)} did not acknowledge its safe position"
        late_signal = stop.pending
        if late_signal and late_signal != exc.interrupted:
            where += f"; {late_signal} received during the safe stop, honoured after it"
        print(f"featherstar: error: {one_line(exc)}{where}", file=sys.stderr)
        return EXIT_FOR_SIGNAL.get(exc.interrupted or "", 2)
    print(summary_table(result.summary))
    for line in stroke_lines(result.scene):
        print(line)
    # The plan's notes (a parameter shared between blocks, a unit check waived) describe the scene
    # as designed, the same on every run: summary.json keeps them, -v prints them.
    for note in result.info.get("notes", []) if args.verbose else ():
        print(f"  note: {note}")
    if args.out:
        paths = _write(result, args.out, figure=not args.no_figure)
        print(f"wrote {', '.join(str(p) for p in paths.values())}")
    if not result.complete:
        print(f"featherstar: error: run incomplete: {result.summary.get('incomplete_reason')}"
              " (see the summary)", file=sys.stderr)
        return 2
    return 0


def stroke_lines(scene) -> list[str]:
    """The console's line per stroke block: its times and its amplitude, which is peak to peak
    (amplitude_deg = 60 swings the root between -30 and +30 degrees)."""
    from .cosim.swimmer.controller import resolve_stroke

    lines = []
    for block in scene.blocks:
        if block.kind != "stroke":
            continue
        s = resolve_stroke(block.settings, block.overrides, block.name)
        lines.append(f"  {'stroke (' + block.name + ')':<30} up {s.t_up_s:g} s, hold {s.t_hold_up_s:g} s, "
                     f"down {s.t_down_s:g} s, hold {s.t_hold_down_s:g} s; amplitude {s.amplitude_deg:g}° "
                     f"peak to peak (±{s.amplitude_deg / 2:g}°)")
    return lines


def _cmd_scenes(args: argparse.Namespace) -> int:
    from .cosim.scenes import list_scenes

    if args.scene:
        return _print_settings(args.scene, args.set)
    rows = list_scenes()
    width = max((len(n) for n, _ in rows), default=0)
    for name, description in rows:
        print(f"{name:<{width}}  {description}")
    return 0


def _print_settings(scene_ref: str, items: list[str]) -> int:
    from .cosim.scene.graph import plan
    from .cosim.scene.listing import format_keys, scene_keys
    from .cosim.scenes import load_scene

    scene = load_scene(scene_ref).with_overrides(_parse_set(items))
    print(f"{scene.name}: every key --set takes (KEY  value unit  range  meaning)")
    print(format_keys(scene_keys(plan(scene))))
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Adds `run` and `scenes` to the featherstar command line."""
    run = sub.add_parser("run", help="run a scene and summarise it (TR, mean thrust, speed)",
                         description="Run a shipped scene (see `featherstar scenes`), a scene TOML file or an "
                         "SSP 1.0 package (see `featherstar export-ssp`).")
    run.add_argument("scene", help="scene name, path to a .toml file, or an SSP 1.0 package (.ssp)")
    run.add_argument("--set", action="extend", nargs="+", default=[], metavar="BLOCK.PARAM=VALUE",
                     help="override block parameters or options, or master.*/metrics.* (one or more per --set, "
                          "repeatable), e.g. --set feather.morphology=spanwise controller.period_s=3 "
                          "master.coupling=jacobi; every key: featherstar scenes SCENE")
    run.add_argument("--out", type=Path, help="write summary.json, results.csv and thrust.png here")
    run.add_argument("--record", help="comma-separated signals to record instead of the scene's (block.port)")
    run.add_argument("--no-figure", action="store_true", help="skip the figure")
    run.add_argument("--hardware", action="append", default=[], metavar="SLOT=URL",
                     help="swap a simulated block for hardware (repeatable): servo=URL, loadcell=URL, with "
                          "URL modbus-tcp://HOST:PORT?unit=N or modbus-rtu:///dev/ttyUSB0?baudrate=...; the run "
                          "is then paced on the wall clock (try it against `featherstar emulate`). URL "
                          "options: unit=N, timeout_s=S (per request, default 0.05), reconnect_s=S (recover "
                          "a lost device for up to S seconds; default: stop), safe_timeout_s=S (servo: retry the safe "
                          "position on stop, default 5); see docs/hil.md")
    run.add_argument("--allow-unactuated-loadcell", action="store_true",
                     help="allow --hardware loadcell without --hardware servo (nothing physical then "
                          "moves the feather the cell reads; the summary carries a warning)")
    run.add_argument("--allow-code", action="store_true",
                     help="let an SSP package name Python code (block factories, model functions) other than "
                          "featherstar's own blocks; a package is data and is refused otherwise (see docs/ssp.md)")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bar (a cold FMU build still says "
                     "what it built and how long it took)")
    run.add_argument("-v", "--verbose", action="store_true",
                     help="also print the plan's notes (parameters shared between blocks, unit checks waived; "
                          "they are in summary.json's info either way)")
    run.set_defaults(func=_cmd_run)
    scenes = sub.add_parser("scenes", help="list the shipped scenes, or every settable key of one",
                            description="Without SCENE: the shipped scenes. With SCENE: every key `--set` takes "
                            "on it (master.*, metrics.*, each block's parameters and build options) with its "
                            "value, unit, range and meaning; --set shows them after overrides (a build "
                            "option such as feather.morphology changes which parameters exist).")
    scenes.add_argument("scene", nargs="?", help="a shipped scene name, a .toml file or an .ssp package")
    scenes.add_argument("--set", action="extend", nargs="+", default=[], metavar="BLOCK.PARAM=VALUE",
                        help="overrides to apply first (one or more per --set)")
    scenes.set_defaults(func=_cmd_scenes)
