"""The `featherstar` command: one parser, its subcommands registered by the packages that own them.

`SUBCOMMANDS` names each module that adds subcommands (through its `register(subparsers)`) and
the subcommands it provides. A module that fails to import, or whose `register` fails, does not
make its subcommands vanish: they stay in `featherstar --help`, marked unavailable with the
error, and running one prints that error (exit status 2).
"""
from __future__ import annotations

import argparse
import importlib
import sys
from dataclasses import dataclass
from typing import Sequence

from .fmu_src.build_progress import reset as reset_build_progress
from .fmu_src.errors import FeatherstarError
from .terminal import EXIT_FOR_SIGNAL, one_line


@dataclass(frozen=True)
class Subcommands:
    """A module offering `register(subparsers)`, and the subcommands it adds."""

    module: str
    names: tuple[str, ...]


SUBCOMMANDS: tuple[Subcommands, ...] = (
    Subcommands("featherstar.run_cli", ("run", "scenes")),
    Subcommands("featherstar.fmu_src.cli", ("build",)),
    Subcommands("featherstar.ssp_cli", ("export-ssp",)),
    Subcommands("featherstar.optimizer.cli", ("optimize", "calibrate", "sweep", "codesign", "paper")),
    Subcommands("featherstar.hil.cli", ("emulate",)),
    Subcommands("featherstar.dashboard", ("bench",)),
)


def _unavailable(sub: argparse._SubParsersAction, entry: Subcommands, error: str) -> None:
    """The entry's subcommands, each saying why it cannot run."""
    message = f"cannot load {entry.module}: {error}"

    def fail(args: argparse.Namespace) -> int:
        print(f"featherstar {args.command}: unavailable: {message}", file=sys.stderr)
        return 2

    known = set(sub.choices)
    for name in entry.names:
        if name in known:
            continue
        parser = sub.add_parser(name, help=f"UNAVAILABLE ({message})", add_help=False)
        parser.add_argument("rest", nargs=argparse.REMAINDER)
        parser.set_defaults(func=fail)


def build_parser(subcommands: Sequence[Subcommands] = SUBCOMMANDS, only: str | None = None) -> argparse.ArgumentParser:
    """The parser with every entry's subcommands, or with only the entry providing `only` (a
    command line that names its subcommand imports only that module: `featherstar run` does not
    pay for scikit-optimize's import)."""
    parser = argparse.ArgumentParser(prog="featherstar", description="Co-simulation toolkit for soft robotic swimmers")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    chosen = [e for e in subcommands if only in e.names]
    for entry in chosen or subcommands:
        try:
            module = importlib.import_module(entry.module)
            module.register(sub)
        except Exception as exc:   # a broken package must not take the other subcommands down
            _unavailable(sub, entry, f"{type(exc).__name__}: {one_line(exc)}")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    named = argv[0] if argv and not argv[0].startswith("-") else None
    parser = build_parser(only=named)
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    reset_build_progress(quiet=getattr(args, "quiet", False))
    try:
        return int(args.func(args) or 0)
    except FeatherstarError as exc:
        print(f"featherstar: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:   # before or after a run: nothing to keep
        name = getattr(exc, "signal_name", "SIGINT")
        print(f"featherstar: interrupted by {name}", file=sys.stderr)
        return EXIT_FOR_SIGNAL.get(name, 130)
