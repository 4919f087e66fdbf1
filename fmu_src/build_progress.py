"""What a cold FMU build tells the user while it runs (seconds for a servo, about two minutes for
an N = 40 feather), on stderr, because a build before a run otherwise sits under a 0 % bar:

    featherstar: building FMU feather_chordwise (1 of 3) ...
    featherstar: still building FMU feather_chordwise: 30 s
    featherstar: built FMU feather_chordwise (1 of 3) in 57.2 s

`quiet` keeps only the last line (the build happened and how long it took). A cached FMU says
nothing. Callers that build several FMUs (a scene's blocks, `featherstar build`) say how many
with `number_builds(total)` and `next_block()`, so each build knows its "n of m".
"""
from __future__ import annotations

import sys
import threading
import time
from contextlib import contextmanager
from typing import Iterator, TextIO

#: Seconds between "still building" lines.
TICK_S = 15.0

_state = {"total": None, "index": 0, "quiet": False}


def reset(quiet: bool = False) -> None:
    """A new command starts: no numbering, and `quiet` as it asked (one line per cold build, when
    it is done: what was built, how long it took). Called by every command, so that state never
    leaks from one command to the next run in the same process (the CLI's tests, notebooks)."""
    _state.update(total=None, index=0, quiet=bool(quiet))


def number_builds(total: int | None) -> None:
    """The caller is about to visit `total` FMUs (built cold or found cached): number them."""
    _state.update(total=total or None, index=0)


def next_block() -> None:
    """The caller moves to its next FMU (counted whether or not it is built cold)."""
    _state["index"] += 1


def _position() -> str:
    total, index = _state["total"], _state["index"]
    return f" ({max(index, 1)} of {total})" if total else ""


@contextmanager
def cold_build(name: str, stream: TextIO | None = None) -> Iterator[None]:
    """Report one cold build of FMU `name`: its start, its elapsed time every TICK_S, its end."""
    out = stream or sys.stderr
    quiet, where = bool(_state["quiet"]), _position()
    started = time.perf_counter()
    done = threading.Event()

    # On a terminal, clear the line first: a progress bar may be drawn there (it redraws itself).
    clear = "\r\033[K" if getattr(out, "isatty", lambda: False)() else ""

    def say(text: str) -> None:
        print(f"{clear}featherstar: {text}", file=out, flush=True)

    def tick() -> None:
        while not done.wait(TICK_S):
            say(f"still building FMU {name}: {time.perf_counter() - started:.0f} s")

    if not quiet:
        say(f"building FMU {name}{where} (cold: not in the build cache) ...")
        threading.Thread(target=tick, daemon=True).start()
    try:
        yield
    except BaseException:
        done.set()
        say(f"building FMU {name}{where} failed after {time.perf_counter() - started:.1f} s")
        raise
    done.set()
    say(f"built FMU {name}{where} in {time.perf_counter() - started:.1f} s")
