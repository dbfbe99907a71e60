"""Many independent runs on Dask distributed: an existing cluster or a local one (ROS-free).

``--scheduler tcp://HOST:PORT`` uses a cluster the user runs (``dask scheduler`` and
``dask worker ADDRESS``, on one machine or many); without it a local cluster of
``--workers`` processes (one thread each: the runs are compiled numba loops that hold the
GIL). Tasks are module-level functions of the package, so every worker needs pdsmc_ros
installed. Dask reschedules the tasks of a worker that dies; results are handed back as
they finish, with their task index, so callers order them and tables do not depend on the
engine or the number of workers.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import sys
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TextIO

from ..errors import ConfigError
from ..glibc import M_MMAP_THRESHOLD, M_TRIM_THRESHOLD, mallopt

SCHEDULER_ADDRESS = re.compile(r"^(tcp|tls|inproc|ws|wss)://[^\s/]+(:\d+)?/?$")
CONNECT_TIMEOUT_S = 10


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A ``distributed.Client``: connected to ``scheduler``, or to a local cluster of ``workers`` processes.

    Raises
    ------
    ConfigError
        One line: a malformed or unreachable scheduler address, or Dask not installed.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:  # pragma: no cover - a runtime dependency
        raise ConfigError("Dask distributed is not installed: run make setup") from exc
    if scheduler is not None:
        if not SCHEDULER_ADDRESS.match(scheduler):
            raise ConfigError(f"--scheduler {scheduler!r}: expected an address like tcp://HOST:PORT")
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError) as exc:
            raise ConfigError(f"--scheduler {scheduler!r}: cannot reach it within {CONNECT_TIMEOUT_S} s "
                              f"({type(exc).__name__})") from None
        try:
            yield client
        finally:
            client.close()
        return
    count = workers or os.cpu_count() or 1
    import dask

    # What a worker does beside its task costs the task CPU on a small machine: the statistical
    # profiler samples the running task's stack every 10 ms, the memory monitors poll every
    # 100 ms (the runs need a few MB), the system monitor every 0.5 s (docs/PERFORMANCE.md).
    # Workers of a local cluster inherit these settings; a user's own cluster keeps its own.
    quiet = {"distributed.worker.profile.enabled": False, "distributed.worker.memory.target": False,
             "distributed.worker.memory.spill": False, "distributed.worker.memory.pause": False,
             "distributed.worker.memory.terminate": False, "distributed.admin.system-monitor.interval": "5s"}
    # Dask's own logs stay out of the command's output: the one worth a user's attention, a worker
    # lost mid-run, is handled (its tasks are redone) and said in our words; at ERROR level a loaded
    # machine printed a worker's failed heartbeat, with its traceback, as the cluster closed.
    with dask.config.set(quiet):
        cluster = LocalCluster(n_workers=count, threads_per_worker=1, processes=True, dashboard_address=None,
                               silence_logs=logging.CRITICAL)
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def run_tasks(client: Any, fn: Callable[..., Any], arguments: Sequence[tuple[Any, ...]], *,
              workers: Sequence[str] | None = None) -> Iterator[tuple[int, Any]]:
    """``(index, fn(*arguments[index]))`` as the tasks finish, on ``client``'s workers (on ``workers``
    only: their addresses, if given).

    On KeyboardInterrupt the tasks not yet finished are cancelled and the interrupt re-raised.
    """
    from distributed import as_completed

    batch = uuid.uuid4().hex  # unique keys per call; "pdsmc_<fn>" is what a dashboard groups them by
    futures = [client.submit(_task, fn, *args, key=f"pdsmc_{fn.__name__}-{i}-{batch}", pure=False,
                             workers=None if workers is None else list(workers))
               for i, args in enumerate(arguments)]
    index = {future.key: i for i, future in enumerate(futures)}
    try:
        for future in as_completed(futures):
            yield index[future.key], future.result()
    except KeyboardInterrupt:
        client.cancel(futures)
        raise


def _task(fn: Callable[..., Any], *args: Any) -> Any:
    """``fn(*args)`` in a worker whose allocator keeps freed memory (:func:`keep_freed_memory`)."""
    keep_freed_memory()
    return fn(*args)


HEAP_ARRAYS_BYTES = 64 << 20
_allocator_set = False


def keep_freed_memory() -> None:
    """Have glibc's allocator keep freed memory for the next run (once per process).

    By default glibc serves an allocation above 128 kB (and up to 32 MB as it adapts) with fresh
    ``mmap``'d pages and returns them on ``free``: a worker that allocates and frees a run's
    arrays thousands of times takes a page fault on every 4 kB of them. 150 five-bar runs x 3 laws:
    3.0 M minor faults and 8.5-9.4 s of system time by default; with arrays up to
    ``HEAP_ARRAYS_BYTES`` from the heap and freed memory kept up to four times that, 0.1 M and
    1.0-1.2 s, the wall time -10 %, the same table (docs/PERFORMANCE.md). Since the five-bar's
    forward position makes no (N, 2) temporaries, a five-bar run's arrays hardly fault by default
    either; what still does is an array above glibc's adaptive ceiling (a long run's samples).
    Not glibc: nothing done.
    """
    global _allocator_set  # noqa: PLW0603 - once per process
    if _allocator_set:
        return
    _allocator_set = True
    mallopt(M_MMAP_THRESHOLD, HEAP_ARRAYS_BYTES)
    mallopt(M_TRIM_THRESHOLD, 4 * HEAP_ARRAYS_BYTES)


class Progress:
    """Runs done of total, rate and time left: a live bar on a terminal, plain lines otherwise."""

    def __init__(self, total: int, label: str, *, stream: TextIO | None = None, width: int = 30) -> None:
        self.total = total
        self.label = label
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.width = width
        self.start = time.monotonic()
        self.done = 0
        self.last_line = -1.0

    def step(self, count: int = 1) -> None:
        self.done += count
        elapsed = time.monotonic() - self.start
        rate = self.done / elapsed if elapsed > 0 else 0.0
        left = (self.total - self.done) / rate if rate > 0 else float("nan")
        text = f"{self.label}: {self.done}/{self.total} runs, {rate:.1f} runs/s, {left:.0f} s left"
        if self.tty:
            filled = int(self.width * self.done / max(self.total, 1))
            self.stream.write(f"\r[{'#' * filled}{'.' * (self.width - filled)}] {text}")
            if self.done >= self.total:
                self.stream.write("\n")
            self.stream.flush()
        elif self.done >= self.total or elapsed - self.last_line >= 10.0 or self.done == 1:
            self.last_line = elapsed
            print(text, file=self.stream, flush=True)
