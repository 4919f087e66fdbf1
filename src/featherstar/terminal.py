"""What the command line prints on the way out, and how it takes stop signals: one-line
errors, the exit status of a signal, and the signal handlers of a run."""
from __future__ import annotations

import contextlib
import signal
import sys
import threading
from typing import Iterator

from .cosim.coupling.pacing import STOP, StopRequest
from .cosim.errors import RunInterrupted

#: The shell's exit status for a run stopped by a signal (128 + its number).
EXIT_FOR_SIGNAL = {"SIGINT": 130, "SIGTERM": 143, "SIGHUP": 129}


def one_line(exc: BaseException) -> str:
    """An error's message on one line (a multi-problem SceneError joined with '; ')."""
    # Drop the "  - " bullets of multi-problem errors, not the dashes of an option's name.
    lines = [ln.strip().removeprefix("- ").strip() for ln in str(exc).splitlines() if ln.strip()]
    if not lines:
        return type(exc).__name__
    return lines[0] + (" " + "; ".join(lines[1:]) if len(lines) > 1 else "")


@contextlib.contextmanager
def stop_signals(*, deferred: bool) -> Iterator[StopRequest]:
    """SIGINT/SIGTERM/SIGHUP stop the run once; repeats are only reported.

    deferred (a run with hardware): a signal is only recorded; the run honours it at its next
    step or wait (featherstar.cosim.coupling.pacing), never inside the safe stop, which then
    runs to its end (safe position commanded, data written). A signal that arrives while a stop
    after a fault is under way is kept too: the caller exits with its status (`exit_status`).
    Not deferred (a simulation, which has no pacer to honour it): the first signal raises
    RunInterrupted at once, as Ctrl-C does.
    """
    STOP.clear()
    if threading.current_thread() is not threading.main_thread():
        yield STOP
        return

    def handler(signum: int, _frame: object) -> None:
        name = signal.Signals(signum).name
        if not STOP.request(name):
            print(f"featherstar: {name} received, still stopping safely", file=sys.stderr)
        elif not deferred:
            raise RunInterrupted(name)

    names = [n for n in EXIT_FOR_SIGNAL if hasattr(signal, n)]
    previous = {n: signal.signal(getattr(signal, n), handler) for n in names}
    try:
        yield STOP
    finally:
        for n, h in previous.items():
            signal.signal(getattr(signal, n), h)


def exit_status(status: int, stop: StopRequest) -> int:
    """The command's exit status: the first stop signal's (128 + its number) if one came."""
    return EXIT_FOR_SIGNAL.get(stop.pending or "", status)
