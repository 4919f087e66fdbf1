"""A foreign binary cannot take the master down: before the master loads an FMU's shared library,
a child process (featherstar.cosim.fmi.probe_child) loads it and takes one instance through
instantiate, initialization, terminate and free. A binary that crashes there (SIGSEGV, SIGBUS from
a truncated library, abort(), exit() from inside the model, a hang) costs the child, and the master
hears one line naming the FMU, the call and the signal.

A binary that got through is remembered by the SHA-256 of its FMU file (and the interface probed)
in featherstar's cache, so the probe costs once per binary and a hash after that; in one process a
file seen unchanged (same inode, size and mtime) is not hashed again. Measured on the testbed's two
FMUs (2 shared cores): 0.38-0.43 s each the first time, 0.2-0.8 ms in a new process, 0 in the same
one. featherstar's own FMUs are probed too, once per build: a build costs seconds of gcc, so
trusting them by hash instead would save little and add a second path to get wrong.

What the probe cannot see: a binary that runs its life cycle cleanly with default start values
and crashes later (in a step, or for other parameters) still takes the process with it; running
every FMU call out of process would cost the hot loop several µs per call.
"""
from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from .probe_child import MARK, READY

#: Bump when the probe's calls change: earlier verdicts no longer count.
PROBE_VERSION = "1"
DEFAULT_TIMEOUT_S = 60.0
_seen: dict[tuple[str, int, int, int, str], bool] = {}


def probe_cache() -> Path:
    from ...fmu_src.export import cache_dir

    return cache_dir() / "probed"


def _key(fmu_path: Path, mode: str) -> str:
    with open(fmu_path, "rb") as fh:
        digest = hashlib.file_digest(fh, "sha256").hexdigest()
    return f"{digest[:40]}-{mode}-v{PROBE_VERSION}"


def probe_fmu(fmu_path: Path, unzip_dir: str | Path, guid: str, model_identifier: str, fmi_version: str,
              mode: str, timeout_s: float = DEFAULT_TIMEOUT_S) -> str | None:
    """Why the FMU's binary cannot be loaded into this process (it crashed, exited or hung in the
    child, naming the call and the signal), or None when it got through (or was probed before)."""
    stat = os.stat(fmu_path)
    seen = (str(fmu_path), stat.st_ino, stat.st_size, stat.st_mtime_ns, mode)
    if _seen.get(seen):
        return None
    key = _key(fmu_path, mode)
    marker = probe_cache() / key
    if marker.is_file():
        _seen[seen] = True
        return None
    problem, clean = _run_child(unzip_dir, guid, model_identifier, fmi_version, mode, timeout_s)
    if problem is None and clean:
        _remember(marker)
        _seen[seen] = True
    return problem


def _remember(marker: Path) -> None:
    """Write the verdict atomically (concurrent probes of one binary agree anyway)."""
    try:
        marker.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=marker.parent, prefix=f".{marker.name}.")
        os.close(fd)
        os.replace(tmp, marker)
    except OSError:   # a read-only cache: probe again next time
        pass


def _run_child(unzip_dir: str | Path, guid: str, identifier: str, version: str, mode: str,
               timeout_s: float) -> tuple[str | None, bool]:
    """(problem or None, whether the child went through every call)."""
    child = Path(__file__).with_name("probe_child.py")
    # -P: not the script's folder on sys.path (its modules would shadow nothing, but need not be seen)
    argv = [sys.executable, "-P", str(child), str(unzip_dir), guid, identifier, version, mode]
    # its own session: a hang is killed with whatever the library started
    with subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True, errors="replace", start_new_session=True) as child_process:
        try:
            stdout, stderr = child_process.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(child_process.pid, signal.SIGKILL)
            stdout, _ = child_process.communicate()
            steps = [s for s in _steps(stdout) if s != READY] or ["load"]
            where = "loading the library" if steps[-1] == "load" else steps[-1]
            return f"did not return from {where} within {timeout_s:g} s (killed)", False
    returncode = child_process.returncode
    steps = _steps(stdout)
    if not steps or steps[0] != READY:   # the probe itself is broken: refuse rather than trust
        said = (stderr or "").strip().splitlines() or [s for s in steps if s.startswith("error ")]
        return f"could not be probed (the probe process failed before loading it: {said[-1] if said else returncode})", False
    steps = steps[1:] or ["load"]
    last = steps[-1]
    if steps[-1] == "done":
        return None, True
    if steps[-1].startswith("error "):
        return None, False   # a refusal the master reports in its own words when it makes the call
    where = "loading the library" if last == "load" else last
    if returncode < 0:
        try:
            name = signal.Signals(-returncode).name
        except ValueError:
            name = f"signal {-returncode}"
        return f"crashed with {name} in {where}", False
    return f"ended the process (exit status {returncode}) in {where}", False


def _steps(stdout: str | None) -> list[str]:
    return [line[len(MARK):].strip() for line in (stdout or "").splitlines() if line.startswith(MARK)]
