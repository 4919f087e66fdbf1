"""The model family's part of report.md: the claims table's range and verdict cells, and the
"Model-form uncertainty" section (the members, what each range means, every claim under every
member, and what the family cost). The numbers come from robustness.family_table."""
from __future__ import annotations

import math
from typing import Mapping

from .plan import FULL, MEMBER_BY_NAME, Resolution
from .robustness import AGREES, DEFAULT, DISAGREES, UNDECIDED


def _number(value: float) -> str:
    return f"{value:.2f}" if isinstance(value, (int, float)) and math.isfinite(value) else "n/a"


def range_cells(row: Mapping) -> str:
    """`lo (member) – hi (member) | verdict | ` for one row of the claims table."""
    (lo, hi), (lo_end, hi_end) = row["range"], row["range_ends"]
    span = "n/a" if lo_end is None else f"{_number(lo)} ({lo_end}) – {_number(hi)} ({hi_end})"
    why = row["robust_reason"].replace("|", "\\|")
    verdict = {AGREES: AGREES, DISAGREES: f"**{DISAGREES}**"}.get(row["robust"], f"*{UNDECIDED}*: {why}")
    return f"{span} | {verdict} | "


def family_summary(table: list[dict], res: Resolution) -> str:
    counts = {v: sum(1 for row in table if row["robust"] == v) for v in (AGREES, DISAGREES, UNDECIDED)}
    reduced = len(res.family) < len(FULL.family)
    return (f"Each simulated number is also given under every member of the model family ({len(res.family)} "
            f"models, one change at a time from the default: wake laws and the ends of the coefficients' documented "
            f"ranges; see \"Model-form uncertainty\" below for the members and for what each range means): "
            f"**{counts[AGREES]} agree robustly, {counts[DISAGREES]} disagree robustly, {counts[UNDECIDED]} are "
            "undecided by the model** "
            "(agrees robustly: inside the band under every member; disagrees robustly: under none, the range on one "
            "side of the band; undecided: the range straddles a band edge, or a member gave no value)."
            + (f" **Reduced family** at this resolution ({len(res.family)} of the full {len(FULL.family)} members: "
               f"{', '.join(n for n in FULL.family if n not in res.family)} left out); a full report runs them all."
               if reduced else ""))


def family_section(data: Mapping, table: list[dict], res: Resolution, timing: Mapping) -> list[str]:
    lines = ["## Model-form uncertainty\n",
             "The feather model is one member of a family: the build option `wake` (none, the default, or one of "
             "three wake laws fitted to plate data) and coefficients known only within a range (docs/model.md, "
             "'Wake memory' and 'Coefficients'). Each claim is recomputed under each member below, one change at a "
             "time from the default, by the same code that judges the default model, and the range over the "
             "default and the members decides the verdict.\n",
             "| member | model | overrides | feathers it changes |", "|---|---|---|---|"]
    for name in res.family:
        member = MEMBER_BY_NAME[name]
        overrides = ", ".join(f"`{k} = {v}`" for k, v in member.overrides)
        what = member.what.replace("|", "\\|")   # a table cell
        lines.append(f"| {name} | {what} | {overrides} | {', '.join(member.morphologies)} |")
    lines += ["", "**What each range means.** A claim about a fixed stroke is re-run under each member: the "
              "member's own answer. A claim about an optimized stroke strictly needs the optimization redone under "
              "each member; the studies named here are (the model's answer), the others' optimum found with the "
              "default model is validated under each member (the prediction's sensitivity to the model: a member's "
              "own optimum could only be better for it). A feather a member does not change keeps its default value "
              "(no hinge on the plain feather).\n",
              "| # | claim | range | verdict | why |", "|---|---|---|---|---|"]
    for i, row in enumerate(table, 1):
        why = row["robust_reason"].replace("|", "\\|")
        lines.append(f"| {i} | {row['claim']} | {row['range_meaning']} | {row['robust']} | {why} |")
    names = [DEFAULT, *res.family]
    lines += ["", "Every claim's value under every member (bold: inside the band):\n",
              "| # | claim | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for i, row in enumerate(table, 1):
        cells = [(f"**{_number(row['family'][n])}**" if row["family_agrees"][n] else _number(row["family"][n]))
                 for n in names]
        lines.append(f"| {i} | {row['id']} | " + " | ".join(cells) + " |")
    family_wall_s = sum(r.get("wall_s", 0.0) for member in data.get("family", {}).values()
                        for kind in member.values() for r in kind.values())
    runs = sum(len(kind) for member in data.get("family", {}).values() for kind in member.values())
    # A report drawn from an older paper.json (or a run that failed early) may lack the total.
    total = (f" of the report's {timing['task_wall_s']:.0f} s of task time (summed over workers)"
             if "task_wall_s" in timing else "")
    lines += ["", f"The family's {runs} runs took {family_wall_s:.0f} s{total}.\n"]
    return lines
