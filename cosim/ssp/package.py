"""An SSP package's files on disk: unzipped once into the FMU cache, keyed by the package's
content, so the FMU paths a scene read from it names stay valid while the run loads them."""
from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import zipfile
from pathlib import Path, PurePosixPath

from ..errors import SceneError


def unpack(path: Path, where: str, ssd_name: str) -> Path:
    """Unzip once into the cache, keyed by the package's content; FMU paths stay valid after the
    call (a run loads its FMUs later)."""
    from ...fmu_src.export import cache_dir

    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    target = cache_dir() / "ssp" / f"{path.stem}-{digest}"
    if target.is_dir():
        return target
    try:
        archive = zipfile.ZipFile(path)
    except zipfile.BadZipFile:
        raise SceneError(f"{where}: not a zip archive (an .ssp is a zip with {ssd_name} at its top)") from None
    with archive:
        for member in archive.namelist():
            parts = PurePosixPath(member).parts
            if PurePosixPath(member).is_absolute() or ".." in parts:
                raise SceneError(f"{where}: archive member '{member}' points outside the package")
        target.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
        try:
            archive.extractall(staging)
            os.replace(staging, target)
        except OSError:
            shutil.rmtree(staging, ignore_errors=True)
            if not target.is_dir():  # not a concurrent unpacker that got there first
                raise
    return target
