"""The optimizer commands' option types: every value's type and range checked once, at parse time.

`optimize`, `sweep`, `codesign`, `calibrate` and `paper` share these argparse types, so a bad
value (a negative seed, `--periods 0`, an infinite `--rest-s`, an `--out` that cannot be
written) is refused before anything is imported, loaded or run, and `one_line_errors` makes
argparse say it the way every other refusal is said: one line, exit status 2. `command` wraps a
subcommand so the warnings it raises (a log repaired on resume, a figure not drawn) are one line
each on stderr too.
"""
from __future__ import annotations

import argparse
import functools
import math
import sys
import warnings
from pathlib import Path
from typing import Callable, NoReturn

from ..cosim.out_dir import out_dir_problem


def count(least: int, what: str = "") -> Callable[[str], int]:
    """A whole number >= least (`what` says why, e.g. 'the random initial points')."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"wants a whole number >= {least}, got {text!r}") from None
        if value < least:
            raise argparse.ArgumentTypeError(f"wants a whole number >= {least}{f' ({what})' if what else ''}, "
                                             f"got {value}")
        return value
    parse.least = least  # type: ignore[attr-defined]  # what the type accepts, for help and tests
    return parse


def number(*, above: float | None = None, at_least: float | None = None) -> Callable[[str], float]:
    """A finite float, > above or >= at_least."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"wants a number, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"wants a finite number, got {text!r}")
        if above is not None and not value > above:
            raise argparse.ArgumentTypeError(f"wants a number > {above:g}, got {value:g}")
        if at_least is not None and not value >= at_least:
            raise argparse.ArgumentTypeError(f"wants a number >= {at_least:g}, got {value:g}")
        return value
    parse.above, parse.at_least = above, at_least  # type: ignore[attr-defined]
    return parse


def out_dir(text: str) -> Path:
    """An output directory that exists and is writable, or can be created where it is asked for."""
    problem = out_dir_problem(Path(text))
    if problem:
        raise argparse.ArgumentTypeError(f"{text!r} {problem}")
    return Path(text)


def one_line_errors(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Make the parser's refusals one line on stderr, exit status 2 (argparse prints the usage
    first, which buries the line that matters; --help still shows it)."""
    def error(message: str) -> NoReturn:
        print(f"{parser.prog}: error: {message} (see --help)", file=sys.stderr)
        raise SystemExit(2)

    parser.error = error  # type: ignore[method-assign]
    return parser


def command(prog: str, fn: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """fn, with every warning it raises printed as one `PROG: warning: ...` line on stderr."""
    @functools.wraps(fn)
    def run(args: argparse.Namespace) -> int:
        def show(message, category, filename, lineno, file=None, line=None) -> None:
            print(f"{prog}: warning: {' '.join(str(message).split())}", file=sys.stderr)

        with warnings.catch_warnings():
            warnings.showwarning = show
            return fn(args)
    return run
