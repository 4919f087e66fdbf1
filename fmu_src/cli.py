"""`featherstar build [MODEL ...] [--fmi {2,3}] [--out DIR] [--force]`: the catalog's models as FMUs.

The `featherstar` entry point (featherstar.app) owns the parser; this module only adds its
subcommand, so that building FMUs needs nothing from cosim.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .errors import FeatherstarError


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `build` subcommand; it dispatches through `args.func(args)`."""
    parser = subparsers.add_parser(
        "build",
        help="build FMI 3.0 or 2.0 FMUs (Model Exchange + Co-Simulation) of catalog models",
        description="Build FMUs of the named catalog models (all when none are named) and "
        "print their paths. Unchanged models come from the build cache "
        "($FEATHERSTAR_CACHE, default ~/.cache/featherstar/fmus).",
    )
    parser.add_argument("--fmi", type=int, choices=(2, 3), default=3, metavar="{2,3}",
                        help="FMI version: 3 (default) or 2, for importers that only read FMI 2.0 "
                        "(PyFMI, OMSimulator, libcosim, ...)")
    parser.add_argument("models", nargs="*", metavar="MODEL", help="catalog model name (default: all)")
    parser.add_argument("--out", type=Path, help="directory for <model>.fmu (default: the cache itself)")
    parser.add_argument("--force", action="store_true", help="rebuild even when a cached FMU is current")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="one line per cold build (what and how long) instead of its start and elapsed time")

    def run(args: argparse.Namespace) -> int:
        # Imported here: the catalog builds every model's equations, which `--help` should not wait for.
        from .build_progress import next_block, number_builds
        from .catalog import MODELS
        from .export import build_fmu

        unknown = [name for name in args.models if name not in MODELS]
        if unknown:
            parser.error(f"unknown model(s) {', '.join(unknown)}; known models: {', '.join(MODELS)}")
        names = args.models or list(MODELS)
        number_builds(len(names))
        for name in names:
            next_block()
            try:
                print(build_fmu(MODELS[name](), args.out, force=args.force, fmi_version=args.fmi), flush=True)
            except FeatherstarError as error:
                print(f"featherstar build: {name}: {error}", file=sys.stderr)
                return 1
        return 0

    parser.set_defaults(func=run)
