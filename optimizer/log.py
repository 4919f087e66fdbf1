"""Append-only JSONL experiment log: the optimizer's only state on disk.

Line 1 is a header describing the run (space, objective, scene, noise, seed); every later line is
one record, written with a single write() and fsync'd before the next experiment starts, with
SIGINT/SIGTERM held back meanwhile, so Ctrl-C or a crash loses at most the experiment in flight.
A line cut short by a hard kill (SIGKILL, power loss) is dropped on resume with a warning, never
half-parsed. Resuming checks that the header matches: a log is never continued with a different
setup. Since format 2 every record carries `digest`, a hash of its own content, so a record edited
by hand (or by a disk) is refused on resume instead of steering the resumed run; what each
command's records must hold is checked by `featherstar.optimizer.resume`.
"""
from __future__ import annotations

import hashlib
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

# 2: every record carries DIGEST_KEY. Format-1 logs (no digests) still resume, checked record by
# record against the plan but without the edit check.
FORMAT_VERSION = 2
DIGEST_KEY = "digest"
_DIGEST_HEX = 16


class LogRepairWarning(UserWarning):
    """A log was repaired on resume (a last line cut by a hard kill was dropped)."""


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


def digest(record: dict) -> str:
    """The fingerprint of a record's content (its canonical JSON, without the digest itself)."""
    content = {k: v for k, v in record.items() if k != DIGEST_KEY}
    return hashlib.sha256(dumps(content).encode()).hexdigest()[:_DIGEST_HEX]


class ExperimentLog:
    """Open with `ExperimentLog.open(path, header, resume=...)`; `records` holds what was read
    (without their digests), `lines` each record's line number in the file."""

    def __init__(self, path: Path, records: list[dict], lines: list[int] | None = None, *,
                 format: int = FORMAT_VERSION) -> None:
        self.path = path
        self.records = records
        self.lines = lines if lines is not None else [0] * len(records)
        self.format = format

    @classmethod
    def open(cls, path: str | os.PathLike, header: dict, *, resume: bool) -> "ExperimentLog":
        path = Path(path)
        wanted = json.loads(dumps({"kind": "header", "format": FORMAT_VERSION, **header}))
        if not path.exists() or path.stat().st_size == 0:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                log = cls(path, [])
                log._write_line(dumps(wanted))
            except OSError as exc:
                raise OptimizerError(f"cannot write the log {path}: {exc.strerror or exc}; choose another --out") from None
            return log
        if not resume:
            raise OptimizerError(
                f"{path} already holds a run: add --resume to continue it (resume=True from Python), or choose "
                "another --out"
            )
        try:
            stored, log = cls.read(path, repair=True)
        except OptimizerError as exc:
            raise OptimizerError(f"cannot resume: {exc}") from None
        if {**stored, "format": FORMAT_VERSION} != wanted:
            raise OptimizerError(
                f"cannot resume {path}: it was written for a different setup ({_header_difference(stored, wanted)})"
            )
        return log

    @classmethod
    def read(cls, path: str | os.PathLike, *, repair: bool = False) -> tuple[dict, "ExperimentLog"]:
        """(header, log) of an existing log, every record checked against its digest (format 2).
        `repair`: truncate a cut last line away (only for a log about to be appended to)."""
        path = Path(path)
        numbered = read_records(path, repair=repair)
        stored = numbered[0][1] if numbered else {}
        if stored.get("kind") != "header":
            raise OptimizerError(f"{path}: its first line is not a log header")
        if stored.get("format") not in (1, FORMAT_VERSION):
            raise OptimizerError(f"{path}: log format {stored.get('format')!r}, this version reads "
                                 f"formats 1 and {FORMAT_VERSION}")
        old_format = stored["format"] == 1
        records, lines = [], []
        for number, record in numbered[1:]:
            if record.get("kind") == "header":
                raise OptimizerError(f"{path}: line {number} is a second header; two runs were "
                                     "mixed in one log")
            if not old_format and record.get(DIGEST_KEY) != digest(record):
                raise OptimizerError(f"{path}: line {number} does not match its digest; the "
                                     "record was edited or damaged (restore it, or choose another --out)")
            records.append({k: v for k, v in record.items() if k != DIGEST_KEY})
            lines.append(number)
        return stored, cls(path, records, lines, format=1 if old_format else FORMAT_VERSION)

    def append(self, record: dict) -> None:
        self.records.append(record)
        self.lines.append((self.lines[-1] if self.lines else 1) + 1)
        content = json.loads(dumps(record))
        if self.format >= 2:
            content[DIGEST_KEY] = digest(content)
        self._write_line(dumps(content))

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


def read_records(path: Path, *, repair: bool = False) -> list[tuple[int, dict]]:
    """(line number, record) of every complete line of a log. A last line without its newline (a
    write cut by a hard kill) is dropped with a LogRepairWarning (and, with `repair`, truncated
    away so the next append starts on a clean line); any other line that is not UTF-8 JSON of a
    record with a `kind` is refused with one line naming it."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise OptimizerError(f"cannot read the log {path}: {exc.strerror or exc}") from None
    complete = raw[: raw.rfind(b"\n") + 1]
    if len(complete) != len(raw):
        warnings.warn(f"{path}: dropping an incomplete last record ({len(raw) - len(complete)} bytes, "
                      "a write cut by a hard kill)", LogRepairWarning, stacklevel=3)
        if repair:
            with open(path, "r+b") as handle:
                handle.truncate(len(complete))
    records = []
    for number, line in enumerate(complete.split(b"\n"), start=1):
        if not line.strip():
            continue
        try:
            record = json.loads(line.decode("utf-8"))
        except UnicodeDecodeError as exc:
            raise OptimizerError(f"{path}: line {number} is not UTF-8 text (byte {exc.start}); "
                                 "the log is damaged") from None
        except json.JSONDecodeError as exc:
            raise OptimizerError(f"{path}: line {number} is not valid JSON ({exc.msg}, column "
                                 f"{exc.colno}); the log is damaged") from None
        if not isinstance(record, dict) or not isinstance(record.get("kind"), str):
            raise OptimizerError(f"{path}: line {number} is not a log record (a JSON object with "
                                 "a kind); the log is damaged")
        records.append((number, record))
    return records


def _header_difference(stored: dict, wanted: dict) -> str:
    keys = sorted(k for k in set(stored) | set(wanted) if k != "format" and stored.get(k) != wanted.get(k))
    return "; ".join(f"{k}: log has {stored.get(k)!r}, now {wanted.get(k)!r}" for k in keys)
