"""Worker processes die with the process that started them.

A local pool's workers wait for tasks on a pipe that every worker holds open, so when the parent
is killed outright (SIGKILL, the OOM killer) no worker ever sees end-of-file: they block forever,
holding memory and any FMU they had loaded. `bind_to_parent` runs first in each worker (the pool's
initializer) and makes two arrangements:

* on Linux, prctl(PR_SET_PDEATHSIG, SIGKILL): the kernel kills the worker the moment its parent
  dies. The kernel ties this to the parent *thread* that forked the worker, so it is asked for
  only when that thread is the main one (`ProcessExecutor` forks its workers at construction);
* everywhere, a daemon thread that polls the parent pid (`WATCH_INTERVAL_S`) and exits the
  worker once it has been re-parented: the portable fallback, and the safety net for workers
  forked by another thread.
"""
from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

PR_SET_PDEATHSIG = 1     # linux/prctl.h
WATCH_INTERVAL_S = 0.5   # how late a worker may notice its parent is gone (without prctl)
ORPHAN_EXIT_STATUS = 70  # EX_SOFTWARE: never mistaken for a task's own exit


def bind_to_parent(parent_pid: int, kernel_signal: bool) -> None:
    """Pool initializer: die when `parent_pid` does (see the module docstring)."""
    if kernel_signal and sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):   # no libc symbol: the watchdog alone
            pass
    if os.getppid() != parent_pid:   # the parent died before prctl took effect
        os._exit(ORPHAN_EXIT_STATUS)
    threading.Thread(target=_watch, args=(parent_pid,), name="featherstar-parent-watch", daemon=True).start()


def _watch(parent_pid: int) -> None:
    while True:
        time.sleep(WATCH_INTERVAL_S)
        if os.getppid() != parent_pid:
            os._exit(ORPHAN_EXIT_STATUS)
