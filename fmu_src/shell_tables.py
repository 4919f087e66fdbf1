"""C tables the FMU shell checks against, appended to CasADi's generated wrap source.

fmu_src/c/ only sees value references; the names (for log lines) and each parameter's valid range
or choices (featherstar.fmu_src.model.Parameter) come from here, indexed by value reference.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET

from .model import Model

TIME_VR = 4294967295  # CasADi's value reference of `time`


def _c_string(text: str) -> str:
    """A C string literal of `text` (UTF-8, every non-ASCII or special byte escaped)."""
    plain = set(range(32, 127)) - set(b'"\\?')
    return '"' + "".join(chr(b) if b in plain else f"\\{b:03o}" for b in text.encode()) + '"'


def _c_double(value: float) -> str:
    return repr(float(value)) if math.isfinite(value) else ("HUGE_VAL" if value > 0 else "-HUGE_VAL")


def variable_tables(model: Model, root: ET.Element) -> str:
    """C tables the shell checks against: every variable's name by value reference, and the
    valid range (or choices) of every parameter, as declared in the Model."""
    by_vr = {int(v.get("valueReference")): v.get("name") for v in root.iter("Float64")}
    n_var = max((vr for vr in by_vr if vr != TIME_VR), default=0) + 1
    names = ",\n  ".join(_c_string(by_vr.get(vr, "?")) for vr in range(n_var))
    vr_of = {name: vr for vr, name in by_vr.items()}
    limits = ["{0.0, 0.0, 0, 0, NULL, \"\"}"] * n_var
    choice_arrays = []
    for p in model.parameters:
        choices = "NULL"
        if p.choices:
            choices = f"fs_choices_{len(choice_arrays)}"
            choice_arrays.append(f"static const double {choices}[] = {{{', '.join(map(_c_double, p.choices))}}};")
        limits[vr_of[p.name]] = (f"{{{_c_double(p.minimum)}, {_c_double(p.maximum)}, {int(p.exclusive_minimum)}, "
                                 f"{len(p.choices or ())}, {choices}, {_c_string(p.unit)}}}")
    separator = ",\n  "
    return ("\n/* Appended by featherstar (fmu_src/export.py): names and parameter ranges. */\n"
            "#include <math.h>\n#include \"fmi3_shell.h\"\n"
            f"#if N_VAR != {n_var}\n#error variable tables do not match CasADi's N_VAR\n#endif\n"
            + "\n".join(choice_arrays) + "\n"
            f"static const char* const fs_var_name[N_VAR] = {{\n  {names}}};\n"
            f"static const fs_limit fs_limit_by_vr[N_VAR] = {{\n  {separator.join(limits)}}};\n")
