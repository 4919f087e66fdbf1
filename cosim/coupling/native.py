"""C compiled at run time with gcc and cached by the hash of its source: the compiled right-hand
side's op interpreter (compiled_rhs.c), CasADi functions of time that blocks offer, and the
monolithic reference.

Libraries live in `$FEATHERSTAR_CACHE/native` (default ~/.cache/featherstar/native). A library is
written under a temporary name and renamed into place, so processes compiling the same source at
once (optimizer workers) never load a half-written file.
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import tempfile
from pathlib import Path
from typing import Sequence

import casadi as ca


class NativeBuildError(RuntimeError):
    """gcc is missing or refused the source."""


def cache_dir() -> Path:
    root = Path(os.environ.get("FEATHERSTAR_CACHE", Path.home() / ".cache" / "featherstar"))
    return root / "native"


def shared_library(name: str, source: str, flags: Sequence[str] = ("-O2",)) -> Path:
    """`source` compiled into a shared library (cached); its path."""
    digest = hashlib.sha256("\0".join([source, *flags]).encode()).hexdigest()[:16]
    target = cache_dir() / f"{name}_{digest}.so"
    if target.exists():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        c_file = Path(tmp) / f"{name}.c"
        c_file.write_text(source)
        built = Path(tmp) / f"{name}.so"
        try:
            result = subprocess.run(["gcc", *flags, "-shared", "-fPIC", str(c_file), "-o", str(built), "-lm"],
                                    capture_output=True, text=True)
        except OSError as exc:
            raise NativeBuildError(f"cannot run gcc: {exc}") from None
        if result.returncode != 0:
            raise NativeBuildError(f"gcc failed on {name}: {result.stderr.strip()[-400:]}")
        os.replace(built, target)
    return target


def casadi_source(functions: Sequence[ca.Function]) -> str:
    """CasADi's generated C for `functions` (each callable by its name), as one source text."""
    with tempfile.TemporaryDirectory() as tmp:
        name = "featherstar_generated.c"
        generator = ca.CodeGenerator(name, {"with_header": False})
        for fn in functions:
            generator.add(fn)
        generator.generate(tmp + os.sep)
        return (Path(tmp) / name).read_text()


def casadi_library(functions: Sequence[ca.Function], flags: Sequence[str] = ("-O2",)) -> Path:
    """The functions' generated C compiled (cached by the generated source)."""
    return shared_library("casadi_" + "_".join(fn.name() for fn in functions)[:40], casadi_source(functions), flags)
