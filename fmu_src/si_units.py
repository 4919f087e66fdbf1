"""SI base-unit exponents of the unit strings models use ("N.m/(rad.s)"): what FMI's <BaseUnit>
and SSP's ssc:BaseUnit declare, so that importers can compare and convert units."""
from __future__ import annotations

import re

# Base-unit exponents of the symbols models use; a unit built from others gets no base unit.
_SI: dict[str, dict[str, int]] = {
    "m": {"m": 1}, "kg": {"kg": 1}, "s": {"s": 1}, "A": {"A": 1}, "K": {"K": 1},
    "mol": {"mol": 1}, "cd": {"cd": 1}, "rad": {"rad": 1}, "Hz": {"s": -1},
    "N": {"kg": 1, "m": 1, "s": -2}, "Pa": {"kg": 1, "m": -1, "s": -2},
    "J": {"kg": 1, "m": 2, "s": -2}, "W": {"kg": 1, "m": 2, "s": -3},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
}


def base_unit(unit: str) -> dict[str, int] | None:
    """SI base exponents of e.g. "N.m/(rad.s)" ({} for "1"); None when a symbol is not known."""
    exponents: dict[str, int] = {}
    numerator, _, denominator = unit.partition("/")
    for sign, part in ((1, numerator), (-1, denominator.strip("()"))):
        if part in ("", "1"):
            continue
        for factor in part.split("."):
            match = re.fullmatch(r"([A-Za-z]+)(-?\d+)?", factor)
            if not match or match[1] not in _SI:
                return None
            for base, exponent in _SI[match[1]].items():
                exponents[base] = exponents.get(base, 0) + sign * exponent * int(match[2] or 1)
    return {base: e for base, e in exponents.items() if e}
