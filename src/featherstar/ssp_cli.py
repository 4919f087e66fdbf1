"""`featherstar export-ssp SCENE --out x.ssp`: a scene as an SSP 1.0 package (featherstar.cosim.ssp.export).

`featherstar run x.ssp` needs nothing from here: load_scene reads .ssp packages itself.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `export-ssp` subcommand; it dispatches through `args.func(args)`."""
    parser = subparsers.add_parser(
        "export-ssp",
        help="write a scene as an SSP 1.0 package (.ssp) for OMSimulator, libcosim, ...",
        description="Write SCENE (a shipped scene or a TOML file) as an SSP 1.0 package: "
        "SystemStructure.ssd with the scene's FMU blocks as components (their FMUs under "
        "resources/), their connections and parameter values. featherstar's own blocks (stroke "
        "controller, constants, recorders), the master and metrics settings travel in an "
        "org.featherstar.scene annotation, so `featherstar run x.ssp` runs the same scene.",
    )
    parser.add_argument("scene", help="scene name or path to a .toml file")
    parser.add_argument("--out", type=Path, required=True, help="the .ssp file to write")
    parser.add_argument("--set", action="extend", nargs="+", default=[], metavar="BLOCK.PARAM=VALUE",
                        help="override block parameters or options, or master.*/metrics.* (one or more per "
                             "--set, repeatable)")
    parser.add_argument("--fmi", type=int, choices=(2, 3), default=3, metavar="{2,3}",
                        help="FMI version of the FMUs built from models (default 3; 2 for importers "
                        "that read FMI 2.0 only); FMU files are packed as they are")
    parser.add_argument("--system-outputs", action="store_true",
                        help="also write the recorded signals as system output connectors (SSP's way to "
                        "expose results; Ecos and libcosim refuse such packages)")

    def run(args: argparse.Namespace) -> int:
        from .cosim.scenes import load_scene
        from .cosim.ssp.export import export_ssp

        overrides = {}
        for item in args.set:
            key, eq, value = item.partition("=")
            if not eq or not key.strip():
                parser.error(f"--set '{item}' must read BLOCK.PARAM=VALUE")
            overrides[key.strip()] = value.strip()
        if args.out.suffix.lower() != ".ssp":
            parser.error(f"--out {args.out}: an SSP package's name ends in .ssp")
        def progress(what: str) -> None:
            print(f"featherstar export-ssp: {what} (built once, then cached)", file=sys.stderr, flush=True)

        print(export_ssp(load_scene(args.scene), args.out, overrides, fmi_version=args.fmi,
                         system_outputs=args.system_outputs, progress=progress))
        return 0

    parser.set_defaults(func=run)
