"""A sidecar child's life: started with pipes, seen stopped, ended, replaced by a spare.

A child is ``python -m <module>`` (a fresh interpreter: none of the loop's threads, locks or
real-time policy), its standard input and output the two pipes of :mod:`.framing`, its standard
error the controller's (its log lines). It ends when its input closes (the controller's process
is gone or stopping). A child stopped by ``SIGSTOP`` (or a debugger) would answer nothing again:
:func:`stopped` sees it in ``/proc`` and the parent kills it (:func:`kill`). :class:`Spare` keeps a
child started ahead, its imports done, that a replacement takes instead of waiting for an
interpreter's start. ROS-free.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys

from .framing import grow


def spawn(module: str) -> subprocess.Popen[bytes]:
    """``python -m module`` with pipes to its standard input and from its standard output, each
    grown to :data:`~.framing.PIPE_SIZE`; its standard error is this process's."""
    process = subprocess.Popen([sys.executable, "-m", module], stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    if process.stdin is None or process.stdout is None:  # pragma: no cover - started with pipes
        raise OSError(f"no pipes to {module}")
    grow(process.stdin.fileno())
    grow(process.stdout.fileno())
    return process


def stopped(pid: int) -> bool:
    """Whether process ``pid`` is stopped (``SIGSTOP``, a debugger): state T or t in ``/proc/PID/stat``."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            state = stat.read().rsplit(b")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state in (b"T", b"t")


def close_pipes(process: subprocess.Popen[bytes]) -> None:
    """Close this side of ``process``'s pipes (its input closed: it ends by itself)."""
    for pipe in (process.stdin, process.stdout):
        if pipe is not None:
            with contextlib.suppress(OSError):
                pipe.close()


def kill(process: subprocess.Popen[bytes], wait_s: float) -> None:
    """Kill ``process`` and reap it (waiting up to ``wait_s``), its pipes closed."""
    with contextlib.suppress(OSError):
        process.kill()
    with contextlib.suppress(subprocess.TimeoutExpired):
        process.wait(timeout=wait_s)
    close_pipes(process)


def end(process: subprocess.Popen[bytes], wait_s: float) -> None:
    """Close ``process``'s input and wait up to ``wait_s`` for it to end (it ends its work first),
    else kill it."""
    close_pipes(process)
    try:
        process.wait(timeout=wait_s)
    except subprocess.TimeoutExpired:
        kill(process, wait_s)


def how_it_ended(code: int | None) -> str:
    """A child's end in words, from its return code (None: still running, its pipes closed)."""
    if code is None:
        return "its pipes closed"
    if code < 0:
        with contextlib.suppress(ValueError):
            return f"killed by {signal.Signals(-code).name}"
    return f"exit status {code}"


def as_child() -> None:
    """A child's first lines: a Ctrl-C to the process group is the parent's to handle, and never
    a real-time policy inherited from a loop's thread."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with contextlib.suppress(OSError, AttributeError):
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))


class Spare:
    """A child of ``module`` started ahead (it imports what it needs and waits for its first
    message), for a replacement to take."""

    def __init__(self, module: str) -> None:
        self.module = module
        self.process: subprocess.Popen[bytes] | None = None

    def ensure(self) -> None:
        """A spare running from now on: started if there is none or it ended."""
        if self.process is None or self.process.poll() is not None:
            with contextlib.suppress(OSError):
                self.process = spawn(self.module)

    def take(self) -> subprocess.Popen[bytes] | None:
        """The spare if it still runs (it is no longer the spare), else None."""
        process, self.process = self.process, None
        return process if process is not None and process.poll() is None else None

    def close(self, wait_s: float) -> None:
        """Kill the spare, if any."""
        process, self.process = self.process, None
        if process is not None:
            kill(process, wait_s)
