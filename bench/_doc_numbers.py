"""The one source of the numbers README.md and docs/ quote: each quoted number carries a marker
naming the JSON value it comes from, and agrees with it to its printed rounding.

    the quick report takes 66 s<!-- from docs/results/cli_durations.json:paper_quick.wall_s -->
    0.1 %<!-- from docs/results/emulator_idle_cpu.json:cpu_share_of_one_core*100 -->

The marker follows the number directly (HTML comments do not render). The key is a dotted path
(list items by index: `rows.0.strong`), optionally scaled (`*100`, `*1e3`). A duration may be
printed as "27 s", "6 min 57 s", "7 min" or "1.6 h" against a key in seconds.

    python bench/_doc_numbers.py                    # every marked number, its value, and mismatches
    python bench/_doc_numbers.py --quote FILE:KEY   # the text to paste for a value (with its marker)

tests/test_doc_numbers.py runs the check. A leading underscore: `featherstar bench` does not run it.
"""
from __future__ import annotations

import argparse
import json
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

MARKER = re.compile(r"<!--\s*from\s+(?P<file>[^\s:]+):(?P<key>[\w.\-]+)(?:\*(?P<scale>[\d.e+\-]+))?\s*-->")
#: The quantity right before a marker: a duration in minutes and seconds, or a number with an optional unit.
QUANTITY = re.compile(
    r"(?:(?P<min>\d+)\s*min\s+(?P<sec>\d+(?:\.\d+)?)\s*s"
    r"|(?P<num>[-+]?\d[\d\u202f ]*(?:\.\d+)?(?:e[-+]?\d+)?)\s*(?P<unit>min|h|ms|µs|s|%|mN|N|×|x)?)"
    r"[\s*)]*$")
DURATION_UNITS = {"s": 1.0, "min": 60.0, "h": 3600.0}
CODE = re.compile(r"`[^`]*`")


@dataclass(frozen=True)
class Quote:
    """One marked number of a document."""
    document: str
    line: int
    text: str          # the number as printed ("6 min 57 s")
    printed: float     # in the printed unit, or seconds for "X min Y s"
    half_ulp: float    # half a unit of the last printed digit (in the same unit)
    unit: str
    source: str        # "docs/results/X.json:key"
    scale: float

    def value(self, root: Path = ROOT) -> float:
        file, key = self.source.split(":", 1)
        node = json.loads((root / file).read_text(encoding="utf-8"))
        for part in key.split("."):
            node = node[int(part)] if isinstance(node, list) else node[part]
        return float(node) * self.scale

    def problem(self, root: Path = ROOT) -> str | None:
        """Why the quote disagrees with its source (None when it agrees within rounding)."""
        try:
            value = self.value(root)
        except (OSError, KeyError, IndexError, ValueError, TypeError) as exc:
            return f"{self.document}:{self.line}: {self.source}: no such value ({type(exc).__name__}: {exc})"
        if self.unit in DURATION_UNITS and self.unit != "s":
            value /= DURATION_UNITS[self.unit]
        if not math.isfinite(value) or abs(self.printed - value) > self.half_ulp * 1.0001:
            return (f"{self.document}:{self.line}: quotes {self.text!r}, {self.source} is {value:.6g}"
                    f"{' ' + self.unit if self.unit else ''}")
        return None


def _half_ulp(digits: str) -> float:
    mantissa, _, exponent = digits.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 0.5 * 10.0 ** (-decimals + (int(exponent) if exponent else 0))


def quotes(document: Path, root: Path = ROOT) -> list[Quote]:
    """Every marked number of `document`; a marker with no number before it is a ValueError."""
    found = []
    rel = document.relative_to(root).as_posix() if document.is_relative_to(root) else str(document)
    for number, line in enumerate(document.read_text(encoding="utf-8").splitlines(), 1):
        line = CODE.sub(lambda m: " " * len(m.group(0)), line)     # a marker shown as code is an example
        for marker in MARKER.finditer(line):
            before = MARKER.sub("", line[: marker.start()])
            m = QUANTITY.search(before)
            if not m:
                raise ValueError(f"{rel}:{number}: a marker with no number before it: {line.strip()[:80]!r}")
            scale = float(marker["scale"]) if marker["scale"] else 1.0
            source = f"{marker['file']}:{marker['key']}"
            if m["min"] is not None:
                printed = 60 * int(m["min"]) + float(m["sec"])
                found.append(Quote(rel, number, m.group(0).strip(" *)"), printed, _half_ulp(m["sec"]), "s", source, scale))
                continue
            digits = re.sub(r"[\u202f ]", "", m["num"])
            found.append(Quote(rel, number, m.group(0).strip(" *)"), float(digits), _half_ulp(digits),
                               m["unit"] or "", source, scale))
    return found


def documents(root: Path = ROOT) -> list[Path]:
    """README.md and every Markdown file under docs/."""
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]


def problems(root: Path = ROOT) -> list[str]:
    out = []
    for document in documents(root):
        try:
            out += [p for q in quotes(document, root) if (p := q.problem(root))]
        except ValueError as exc:
            out.append(str(exc))
    return out


def format_duration(seconds: float) -> str:
    """A duration as the docs print it: "27 s", "6 min 57 s", "1.6 h"."""
    if seconds < 60:
        return f"{seconds:.0f} s"
    if seconds < 3600:
        minutes, rest = divmod(round(seconds), 60)
        return f"{minutes} min {rest} s"
    return f"{seconds / 3600:.1f} h"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quote", metavar="FILE:KEY", help="print the text to paste for one value")
    args = parser.parse_args(argv)
    if args.quote:
        quote = Quote("-", 0, "", 0.0, 0.0, "", args.quote, 1.0)
        value = quote.value()
        text = format_duration(value) if args.quote.endswith("_s") else f"{value:.3g}"
        print(f"{text}<!-- from {args.quote} -->")
        return 0
    for document in documents():
        for q in quotes(document):
            print(f"{q.document}:{q.line}: {q.text!r} <- {q.source} = {q.value():.6g}")
    bad = problems()
    for line in bad:
        print(f"MISMATCH {line}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
