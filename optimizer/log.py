"""Append-only JSONL experiment log: the optimizer's only state on disk.

Line 1 is a header describing the run (space, objective, scene, noise, seed); every later line is
one record, written with a single write() and fsync'd before the next experiment starts, with
SIGINT/SIGTERM held back meanwhile, so Ctrl-C or a crash loses at most the experiment in flight.
A line cut short by a hard kill (SIGKILL, power loss) is dropped on resume, never half-parsed.
Resuming checks that the header matches: a log is never continued with a different setup.
"""
from __future__ import annotations

import json
import os
import signal
import threading
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

from ..cosim.jsonable import json_safe

from .errors import OptimizerError

FORMAT_VERSION = 1


@contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold back SIGINT/SIGTERM while a record is written, so it is never cut by Ctrl-C."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def dumps(value: Any) -> str:
    return json.dumps(json_safe(value), sort_keys=True, allow_nan=False)


class ExperimentLog:
    """Open with `ExperimentLog.open(path, header, resume=...)`; `records` holds what was read."""

    def __init__(self, path: Path, records: list[dict]) -> None:
        self.path = path
        self.records = records

    @classmethod
    def open(cls, path: str | os.PathLike, header: dict, *, resume: bool) -> "ExperimentLog":
        path = Path(path)
        header = {"kind": "header", "format": FORMAT_VERSION, **header}
        if not path.exists() or path.stat().st_size == 0:
            path.parent.mkdir(parents=True, exist_ok=True)
            log = cls(path, [])
            log._write_line(dumps(header))
            return log
        if not resume:
            raise OptimizerError(
                f"{path} already holds a run; pass resume=True (--resume) to continue it, or choose "
                "another output directory"
            )
        lines = _read_complete_lines(path)
        stored = json.loads(lines[0]) if lines else None
        if stored != json.loads(dumps(header)):
            raise OptimizerError(
                f"cannot resume {path}: it was written for a different setup "
                f"({_header_difference(stored, json.loads(dumps(header)))})"
            )
        return cls(path, [json.loads(line) for line in lines[1:]])

    def append(self, record: dict) -> None:
        self.records.append(record)
        self._write_line(dumps(record))

    def _write_line(self, line: str) -> None:
        data = (line + "\n").encode()
        with _signals_deferred():
            fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
            try:
                written = os.write(fd, data)
                if written != len(data):
                    raise OptimizerError(f"short write to {self.path}: {written} of {len(data)} bytes")
                os.fsync(fd)
            finally:
                os.close(fd)


def _read_complete_lines(path: Path) -> list[str]:
    """Lines of the log; a last line without its newline (a write cut by a hard kill) is dropped
    and truncated away so the next append starts on a clean line."""
    raw = path.read_bytes()
    complete = raw[: raw.rfind(b"\n") + 1]
    if len(complete) != len(raw):
        warnings.warn(f"{path}: dropping an incomplete last record ({len(raw) - len(complete)} bytes)", stacklevel=3)
        with open(path, "r+b") as handle:
            handle.truncate(len(complete))
    lines = [line for line in complete.decode().splitlines() if line.strip()]
    for number, line in enumerate(lines, start=1):
        try:
            json.loads(line)
        except json.JSONDecodeError as exc:
            raise OptimizerError(f"{path}:{number} is not valid JSON ({exc}); the log is corrupt") from exc
    return lines


def _header_difference(stored: dict | None, wanted: dict) -> str:
    if stored is None:
        return "no header"
    keys = sorted(k for k in set(stored) | set(wanted) if stored.get(k) != wanted.get(k))
    return "; ".join(f"{k}: log has {stored.get(k)!r}, now {wanted.get(k)!r}" for k in keys)
