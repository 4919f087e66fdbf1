"""Run records on disk: samples as CSV, flushed periodically, and a fault note.

A run directory holds
    samples.csv   one row per sample; the header comes from the first row's keys
    run.json      summary written when the run ends, however it ends
    fault.json    only when the run stopped on an exception: device, fault, time, message

Rows reach the operating system at least every `flush_s`, so a crash of the process loses at
most the last flush interval (a power cut can lose what the OS had not yet written).
"""
from __future__ import annotations

import csv
import datetime as _dt
import json
import math
import time
from pathlib import Path
from typing import Mapping

from .errors import DeviceFault


class Recorder:
    """Appends sample rows to `out_dir/samples.csv`."""

    def __init__(self, out_dir: str | Path, *, flush_s: float = 0.5) -> None:
        if not flush_s > 0:
            raise ValueError(f"flush_s must be positive, got {flush_s}")
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.samples_csv = self.out_dir / "samples.csv"
        self.flush_s = flush_s
        self.n_rows = 0
        self.last_row: dict[str, float] = {}
        self._file = self.samples_csv.open("w", newline="", encoding="utf-8")
        self._writer = csv.writer(self._file)
        self._columns: list[str] | None = None
        self._last_flush = time.monotonic()

    @property
    def columns(self) -> list[str]:
        return list(self._columns or [])

    def write(self, row: Mapping[str, float]) -> None:
        """Append one sample; a key missing from later rows is written empty, a key the first
        row did not have is an error (the CSV header is already on disk)."""
        if self._columns is None:
            self._columns = list(row)
            self._writer.writerow(self._columns)
        elif not row.keys() <= set(self._columns):
            raise ValueError(f"sample has keys {sorted(set(row) - set(self._columns))} "
                             f"that the first sample did not have")
        self._writer.writerow([row.get(c, "") for c in self._columns])
        self.n_rows += 1
        self.last_row = dict(row)
        now = time.monotonic()
        if now - self._last_flush >= self.flush_s:
            self._file.flush()
            self._last_flush = now

    def write_fault(self, exc: BaseException) -> Path:
        """Write fault.json describing why the run stopped; returns its path."""
        note: dict[str, object] = {
            "type": type(exc).__name__, "message": str(exc),
            "samples_written": self.n_rows, "samples_csv": self.samples_csv.name,
            "last_sample": {k: v for k, v in self.last_row.items()
                            if not (isinstance(v, float) and not math.isfinite(v))}}
        if isinstance(exc, DeviceFault):
            note.update(exc.to_dict())
        else:
            note.update(device=None, fault=type(exc).__name__,
                        wall_time=_dt.datetime.now(_dt.timezone.utc).isoformat(
                            timespec="milliseconds"))
        path = self.out_dir / "fault.json"
        path.write_text(json.dumps(note, indent=2) + "\n", encoding="utf-8")
        return path

    def write_json(self, name: str, data: Mapping[str, object]) -> Path:
        path = self.out_dir / name
        path.write_text(json.dumps(data, indent=2, default=str) + "\n", encoding="utf-8")
        return path

    def close(self) -> None:
        if not self._file.closed:
            self._file.flush()
            self._file.close()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
