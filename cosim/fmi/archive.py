"""Checks of an FMU archive before anything of it is read: its central directory within the bounds
of featherstar.cosim.fmi.bounded_zip (member count and sizes, compression ratio, names inside
the archive: a bomb is refused before its modelDescription.xml is read into memory), every
member's CRC (a truncated download), and a cached FMU that went bad (rebuilt once). A binary
that passes and still crashes is featherstar.cosim.fmi.probe's business."""
from __future__ import annotations

import logging
import zipfile
from pathlib import Path
from typing import Any, Callable

from ..errors import SceneError
from .bounded_zip import check_zip

log = logging.getLogger(__name__)


def fmu_archive_problem(path: Path) -> str | None:
    """Why the FMU archive at `path` is unusable (bad zip, out of bounds, failed CRC), or None."""
    try:
        with zipfile.ZipFile(path) as archive:
            check_zip(archive, "archive")
            bad = archive.testzip()
    except SceneError as exc:
        return str(exc).removeprefix("archive: ")
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        return f"not a readable zip archive ({exc})"
    except Exception as exc:   # zlib errors on a truncated member, and the like
        return f"damaged archive ({type(exc).__name__}: {exc})"
    return None if bad is None else f"member {bad} fails its CRC check (truncated or damaged)"


def check_fmu_archive(path: Path, where: str) -> None:
    problem = fmu_archive_problem(path)
    if problem is not None:
        raise SceneError(f"{where}: FMU '{path}': {problem}")


def cached_fmu(model: Any, build: Callable[..., Path], where: str) -> Path:
    """The model's cached FMU; a cache entry that fails its CRC is rebuilt once (logged)."""
    path = Path(build(model))
    problem = fmu_archive_problem(path)
    if problem is None:
        return path
    log.warning("%s: cached FMU %s is corrupt (%s); rebuilding it", where, path, problem)
    path = Path(build(model, force=True))
    check_fmu_archive(path, where)
    return path
