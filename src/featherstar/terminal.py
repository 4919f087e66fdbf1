"""What the command line prints on the way out: one-line errors and the exit status of a signal."""
from __future__ import annotations

#: The shell's exit status for a run stopped by a signal (128 + its number).
EXIT_FOR_SIGNAL = {"SIGINT": 130, "SIGTERM": 143, "SIGHUP": 129}


def one_line(exc: BaseException) -> str:
    """An error's message on one line (a multi-problem SceneError joined with '; ')."""
    # Drop the "  - " bullets of multi-problem errors, not the dashes of an option's name.
    lines = [ln.strip().removeprefix("- ").strip() for ln in str(exc).splitlines() if ln.strip()]
    if not lines:
        return type(exc).__name__
    return lines[0] + (" " + "; ".join(lines[1:]) if len(lines) > 1 else "")
