"""Whether an output directory can be written, asked before any work (one check for every
command's `--out`): a refusal after a long run would lose it."""
from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path


def out_dir_problem(path: Path) -> str | None:
    """Why `path` cannot serve as an output directory (it is a file, or neither it nor the
    directory it would be created in can be written), or None when it can."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        return "is a file, not a directory"
    parent = path
    while not parent.exists():
        if parent.parent == parent:
            break
        parent = parent.parent
    if not parent.is_dir():
        return f"cannot be created: {parent} is not a directory"
    try:   # what the command will do there, tried and undone (os.access says yes to root on /proc)
        os.rmdir(tempfile.mkdtemp(prefix=".featherstar-probe-", dir=parent))
    except OSError as exc:
        return f"is not writable: {parent} {_refusal(exc)}"
    return None


def _refusal(exc: OSError) -> str:
    """Why a directory could not be made in an existing one, in words that fit that case (a
    virtual file system such as /proc answers "No such file or directory")."""
    if exc.errno in (errno.EACCES, errno.EPERM):
        return "does not let this user create files"
    if exc.errno == errno.EROFS:
        return "is on a read-only file system"
    if exc.errno == errno.ENOSPC:
        return "is on a full disk"
    if exc.errno == errno.ENOENT:
        return "refuses new directories (a virtual file system?)"
    return f"refuses a new directory ({exc.strerror or exc})"
