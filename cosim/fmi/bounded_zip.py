"""Zip archives from elsewhere (SSP packages, FMUs) read within bounds: every member is checked
against the archive's central directory before a byte is written (count, size, total, compression
ratio, names that would land outside the target, links, encryption), then streamed to disk in
chunks while the bytes actually written are counted (a forged size in the directory cannot buy
more), into a staging folder that is renamed into place only when everything is in. A refused
archive leaves nothing behind: the refusal is one line naming the archive, the member and the
bound it breaks.
"""
from __future__ import annotations

import os
import shutil
import stat
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from ..errors import SceneError

MiB = 1 << 20
CHUNK_BYTES = MiB


@dataclass(frozen=True)
class ZipLimits:
    """What one archive may hold. The defaults fit any FMU or SSP package featherstar has seen
    (the largest feather FMU is 1.4 MB) with two orders of magnitude to spare, and refuse the
    3.9 MB package that unpacks to 3.1 GB (ratio ~800)."""

    max_members: int = 10_000
    max_member_bytes: int = 512 * MiB
    max_total_bytes: int = 1024 * MiB
    #: uncompressed / compressed size; deflate reaches ~1030 on zeros, real files 2-30
    max_ratio: float = 100.0
    #: members smaller than this are not judged by ratio (a small XML may compress 50x)
    ratio_floor_bytes: int = 1 * MiB


DEFAULT_LIMITS = ZipLimits()


def _size(n_bytes: float) -> str:
    return f"{n_bytes / MiB:.1f} MB" if n_bytes >= MiB else f"{n_bytes / 1024:.0f} kB"


def _member_problem(info: zipfile.ZipInfo, limits: ZipLimits) -> str | None:
    name = info.filename
    path = PurePosixPath(name)
    if "\\" in name or "\x00" in name or (len(name) > 1 and name[1] == ":"):
        return "has a Windows or NUL path (backslash, drive letter)"
    if path.is_absolute() or ".." in path.parts:
        return "points outside the package"
    if stat.S_ISLNK(info.external_attr >> 16):
        return "is a symbolic link"
    if info.flag_bits & 0x1:
        return "is encrypted"
    if info.file_size > limits.max_member_bytes:
        return f"unpacks to {_size(info.file_size)}, over the {_size(limits.max_member_bytes)} a member may hold"
    if info.file_size >= limits.ratio_floor_bytes and info.file_size > limits.max_ratio * max(info.compress_size, 1):
        return (f"unpacks {info.file_size / max(info.compress_size, 1):.0f} times its compressed size, over the "
                f"{limits.max_ratio:.0f}x a real file reaches (a zip bomb)")
    return None


def check_zip(archive: zipfile.ZipFile, label: str, limits: ZipLimits = DEFAULT_LIMITS) -> int:
    """Refuse (SceneError, one line) an archive whose central directory breaks `limits`; returns
    the bytes it would unpack to."""
    members = archive.infolist()
    if len(members) > limits.max_members:
        raise SceneError(f"{label}: holds {len(members)} members, over the {limits.max_members} an archive may hold")
    seen: set[str] = set()
    files: dict[str, str] = {}   # a file's path -> its member name (a file may not also be a folder)
    folders: dict[str, str] = {}
    total = 0
    for info in members:
        problem = _member_problem(info, limits)
        if problem is not None:
            raise SceneError(f"{label}: archive member '{info.filename}' {problem}")
        key = str(PurePosixPath(info.filename))
        if key in seen:
            raise SceneError(f"{label}: archive member '{info.filename}' appears twice")
        seen.add(key)
        new_folders = [str(parent) for parent in PurePosixPath(key).parents if str(parent) != "."]
        if info.is_dir():
            new_folders.append(key)
        else:
            files[key] = info.filename
        for folder in new_folders:
            folders.setdefault(folder, info.filename)
        for clash in [f for f in new_folders if f in files] + ([] if info.is_dir() or key not in folders else [key]):
            raise SceneError(f"{label}: archive member '{files[clash]}' is a file where member "
                             f"'{folders[clash]}' needs a folder")
        total += info.file_size
        if total > limits.max_total_bytes:
            raise SceneError(f"{label}: unpacks to more than {_size(limits.max_total_bytes)} (the bound of one "
                             f"archive; reached at member '{info.filename}')")
    return total


def _stream(archive: zipfile.ZipFile, info: zipfile.ZipInfo, target: Path, label: str, budget: int) -> int:
    """Copy one member in chunks; refuse once it writes more than its declared size or the budget."""
    written = 0
    with archive.open(info) as source, open(target, "wb") as out:
        while chunk := source.read(CHUNK_BYTES):
            written += len(chunk)
            if written > info.file_size or written > budget:
                raise SceneError(f"{label}: archive member '{info.filename}' unpacks to more than its declared "
                                 f"{info.file_size} bytes (a forged size)")
            out.write(chunk)
    return written


def extract_bounded(path: Path, target: Path, label: str, limits: ZipLimits = DEFAULT_LIMITS,
                    quota: tuple[Path, int] | None = None) -> Path:
    """Unpack the zip at `path` into `target` (absent or an empty folder), within `limits` and, with
    `quota = (folder, bytes)`, within what `folder` may hold in all. Staged beside `target` and
    renamed into place: on any refusal or failure nothing is left. A concurrent unpacker that
    got there first wins (its folder is returned)."""
    try:
        archive = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        raise SceneError(f"{label}: not a zip archive ({exc})") from None
    with archive:
        total = check_zip(archive, label, limits)
        target.parent.mkdir(parents=True, exist_ok=True)
        if quota is not None:
            _check_quota(quota, total, label)
        free = shutil.disk_usage(target.parent).free
        if total + 64 * MiB > free:
            raise SceneError(f"{label}: unpacks to {_size(total)} but {target.parent} has {_size(free)} free")
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
        try:
            budget = total
            for info in archive.infolist():
                out = staging / PurePosixPath(info.filename)
                if info.is_dir():
                    out.mkdir(parents=True, exist_ok=True)
                    continue
                out.parent.mkdir(parents=True, exist_ok=True)
                budget -= _stream(archive, info, out, label, budget)
            try:
                os.replace(staging, target)
            except OSError:
                if not target.is_dir():   # not a concurrent unpacker that got there first
                    raise
                shutil.rmtree(staging, ignore_errors=True)
        except SceneError:
            shutil.rmtree(staging, ignore_errors=True)
            raise
        except (zipfile.BadZipFile, EOFError, OSError, NotImplementedError, RuntimeError, ValueError) as exc:
            shutil.rmtree(staging, ignore_errors=True)
            raise SceneError(f"{label}: cannot unpack ({type(exc).__name__}: {exc}; truncated, damaged or an "
                             "unsupported compression)") from None
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            raise
    return target


def folder_bytes(folder: Path) -> int:
    """Bytes held by the files under `folder` (0 if it does not exist)."""
    total = 0
    for root, _dirs, files in os.walk(folder):
        for name in files:
            try:
                total += os.lstat(os.path.join(root, name)).st_size
            except OSError:
                pass
    return total


def _check_quota(quota: tuple[Path, int], total: int, label: str) -> None:
    folder, limit = quota
    used = folder_bytes(folder)
    if used + total > limit:
        raise SceneError(f"{label}: unpacks to {_size(total)} but the cache {folder} holds {_size(used)} "
                         f"of its {_size(limit)} quota (remove packages you no longer run from it, or raise "
                         "FEATHERSTAR_SSP_CACHE_MB)")
