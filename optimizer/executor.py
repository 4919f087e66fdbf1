"""Where experiments run: this process, local processes or a Dask cluster, behind one interface.

    with make_executor(scheduler="tcp://host:8786") as executor:     # or workers=N, or nothing
        futures = [executor.submit(fn, *args) for args in work]
        for future in executor.as_completed(futures):
            use(future.result())

Sweeps, the Bayesian optimizer's batches, co-design and `featherstar paper` all submit through an
`Executor`; none of them knows which kind it got. Task functions and their arguments must be
picklable (module-level functions, dataclasses); a task's exception comes back from `result()`.

On a Dask cluster a task whose worker dies (killed, out of memory, host lost) is run again on
another worker by the scheduler; callers see each future complete once. `pure=False`: every task
is a new experiment (its own noise), so the scheduler never merges two submissions of one call.
"""
from __future__ import annotations

import concurrent.futures
import os
import socket
import sys
import threading
from abc import ABC, abstractmethod
from typing import Any, Callable, Collection, Iterator

from tqdm import tqdm

from .errors import OptimizerError
from .lifeline import bind_to_parent

# How long a client waits for the scheduler before calling the address unreachable.
DASK_CONNECT_TIMEOUT_S = 10.0


class Executor(ABC):
    """Submit callables, wait for them as they complete. Use as a context manager."""

    @property
    @abstractmethod
    def slots(self) -> int:
        """How many tasks can run at once (worker processes or cluster threads, at least 1)."""

    @abstractmethod
    def submit(self, fn: Callable[..., Any], /, *args: Any) -> Any:
        """Schedule fn(*args); returns a future with done(), result() and cancel()."""

    @abstractmethod
    def wait_any(self, pending: Collection[Any]) -> set[Any]:
        """Block until at least one of `pending` is done; return the done ones."""

    def describe(self) -> str:
        return f"{type(self).__name__} ({self.slots} at once)"

    def close(self) -> None:
        """Release workers or the cluster connection; pending tasks are cancelled."""

    def as_completed(self, futures: Collection[Any]) -> Iterator[Any]:
        """Each future once, in the order they complete."""
        pending = set(futures)
        while pending:
            done = self.wait_any(pending)
            pending -= done
            yield from done

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _Deferred(concurrent.futures.Future):
    """A task of the InlineExecutor: it runs when first waited for, not when submitted."""

    def __init__(self, order: int, fn: Callable[..., Any], args: tuple) -> None:
        super().__init__()
        self.order = order
        self._call: tuple[Callable[..., Any], tuple] | None = (fn, args)

    def run(self) -> None:
        if self._call is None:
            return
        fn, args = self._call
        self._call = None
        try:
            self.set_result(fn(*args))
        except Exception as exc:  # noqa: BLE001 — handed back through result(), as the other executors do
            self.set_exception(exc)

    def result(self, timeout: float | None = None) -> Any:
        self.run()
        return super().result(timeout)


class InlineExecutor(Executor):
    """Runs tasks in this process, one at a time, in the order submitted, each when it is first
    waited for: a caller streaming results to disk writes each before the next one starts. No
    pickling, so anything callable works; the simplest to debug."""

    def __init__(self) -> None:
        self._submitted = 0

    @property
    def slots(self) -> int:
        return 1

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> _Deferred:
        self._submitted += 1
        return _Deferred(self._submitted, fn, args)

    def wait_any(self, pending: Collection[Any]) -> set[Any]:
        done = {future for future in pending if future.done()}
        if not done:
            first = min(pending, key=lambda future: future.order)
            first.run()
            done = {first}
        return done

    def describe(self) -> str:
        return "this process"


class ProcessExecutor(Executor):
    """Local worker processes (Python's default start method: forked on Linux, so workers start
    without re-importing anything; objectives load their scene lazily, so no FMU handle crosses
    the fork). The workers die with this process, however it dies (featherstar.optimizer.lifeline)."""

    def __init__(self, workers: int | None = None) -> None:
        if workers is not None and workers < 1:
            raise OptimizerError(f"workers = {workers} must be >= 1")
        self._workers = workers or os.cpu_count() or 1
        main = threading.current_thread() is threading.main_thread()
        self._pool = concurrent.futures.ProcessPoolExecutor(
            max_workers=self._workers, initializer=bind_to_parent, initargs=(os.getpid(), main))
        # Fork the workers now, from this thread: the kernel's parent-death signal follows the
        # forking thread, so they must not be forked by a thread that ends before the pool.
        self._pool.submit(int).result()

    @property
    def slots(self) -> int:
        return self._workers

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> concurrent.futures.Future:
        return self._pool.submit(fn, *args)

    def wait_any(self, pending: Collection[Any]) -> set[Any]:
        done, _ = concurrent.futures.wait(pending, return_when=concurrent.futures.FIRST_COMPLETED)
        return set(done)

    def describe(self) -> str:
        return f"{self._workers} local processes"

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


class DaskExecutor(Executor):
    """A client of a running Dask scheduler (`dask scheduler` + `dask worker ADDRESS` on each host)."""

    def __init__(self, address: str, *, connect_timeout_s: float = DASK_CONNECT_TIMEOUT_S) -> None:
        try:
            from dask.distributed import Client, as_completed
        except ImportError as exc:
            raise OptimizerError(
                f"a Dask scheduler address ({address}) was given but dask.distributed is not installed; "
                "install it with pip install 'featherstar[dask]', or drop --scheduler to use local processes"
            ) from exc
        self.address = address
        try:
            _probe(address, connect_timeout_s)
            self._client = Client(address, timeout=connect_timeout_s, set_as_default=False)
        except Exception as exc:  # noqa: BLE001 — bad scheme, refused, timed out: all one message
            reason = " ".join(str(exc).split()) or type(exc).__name__
            raise OptimizerError(f"cannot connect to the Dask scheduler at {address!r}: {reason}") from None
        self._completed = as_completed(loop=self._client.loop)
        self._finished: set[Any] = set()

    @property
    def slots(self) -> int:
        return max(1, sum(self._client.nthreads().values()))

    @property
    def dashboard_link(self) -> str | None:
        """The scheduler's dashboard URL, None when it runs none (bokeh not installed there)."""
        try:
            return self._client.dashboard_link
        except (KeyError, AttributeError):
            return None

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> Any:
        future = self._client.submit(fn, *args, pure=False)
        self._completed.add(future)
        return future

    def wait_any(self, pending: Collection[Any]) -> set[Any]:
        # One as_completed tracks every future submitted here (a new one per call would start a
        # watcher per pending future each time); finished ones wait in _finished until asked for.
        pending = set(pending)
        while not self._finished & pending:
            self._finished.update(self._completed.next_batch(block=True))
        done = self._finished & pending
        self._finished -= done
        return done

    def describe(self) -> str:
        workers = len(self._client.nthreads())
        dashboard = self.dashboard_link or "none (install bokeh on the scheduler)"
        return f"Dask scheduler {self.address}: {workers} workers, {self.slots} threads; dashboard {dashboard}"

    def close(self) -> None:
        self._client.close()


def _probe(address: str, timeout_s: float) -> None:
    """Fail fast on a malformed or unreachable TCP address: a Client that fails to connect keeps
    retrying until its timeout, then blocks another 20 s in its finalizer."""
    from distributed.comm import parse_address, parse_host_port

    scheme, location = parse_address(address)
    if scheme not in ("tcp", "tls", "inproc", "ws", "wss", "ucx"):
        raise ValueError(f"unknown address scheme {scheme!r} (tcp://HOST:PORT, as `dask scheduler` prints)")
    if scheme in ("tcp", "tls"):
        host, port = parse_host_port(location)
        socket.create_connection((host, port), timeout=timeout_s).close()


def make_executor(scheduler: str | None = None, workers: int | None = None) -> Executor:
    """A Dask client when `scheduler` is given, else `workers` local processes (None: all cores;
    1: this process)."""
    if scheduler:
        return DaskExecutor(scheduler)
    if workers == 1:
        return InlineExecutor()
    return ProcessExecutor(workers)


class Progress:
    """A bar on stderr: done of total, with running and failed counts beside it."""

    def __init__(self, total: int, label: str, *, enabled: bool = True, initial: int = 0) -> None:
        self._bar = tqdm(total=total, initial=initial, desc=label, unit="task", file=sys.stderr, disable=not enabled)
        self.failed = 0

    def update(self, *, running: int, failed: bool = False, note: str = "") -> None:
        """One task finished; `running`: how many are still in flight."""
        self.failed += bool(failed)
        postfix = f"running {running}, failed {self.failed}" + (f", {note}" if note else "")
        self._bar.set_postfix_str(postfix, refresh=False)
        self._bar.update()

    def close(self) -> None:
        self._bar.close()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
