"""Run a command with busy processes competing for the cores, as issue 25's "done when" asks:

    python bench/_under_load.py --busy 2 -- python -m pytest -q tests/hil

starts `--busy` processes of `python -c "while True: pass"`, runs the command, kills them (also
when the command fails or is interrupted) and prints the command's wall time and exit status.
Exits with the command's status. The timed-load benches start their busy processes with
`busy_processes` from here. A helper, not a benchmark (so the dashboard does not schedule it).
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import time
from contextlib import contextmanager
from typing import Iterator

BUSY = [sys.executable, "-c", "while True: pass"]


@contextmanager
def busy_processes(count: int, warm_up_s: float = 0.5) -> Iterator[None]:
    """`count` processes spinning on a core for the duration of the block, killed on every exit."""
    hogs = [subprocess.Popen(BUSY) for _ in range(count)]
    try:
        time.sleep(warm_up_s if count else 0.0)
        yield
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--busy", type=int, default=2, help="busy processes (default %(default)s)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- COMMAND ...")
    args = parser.parse_args()
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("give the command after --")
    started = time.monotonic()
    with busy_processes(args.busy, warm_up_s=0.0):
        status = subprocess.call(command)
    print(f"under_load: {args.busy} busy, {time.monotonic() - started:.1f} s wall, exit {status}: "
          f"{' '.join(command)}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
