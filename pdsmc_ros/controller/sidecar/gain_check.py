"""The stability check of new gains, and where it runs: in the caller, or in a process of its own.

A gain change passes the zero-order-hold stability check of start-up at the running rate
(:func:`~pdsmc_ros.control.stability.check_rate`) or is refused with the reason. The check is
50-100 ms of numpy (eigenvalues along the reference). Run in a real-time controller's process, it
holds the interpreter's lock beside the control loop: ``bench/storm.py --roles params`` measured
the loop's p99 lateness 4.2 times its idle value, and with a core busy the driver's states went
stale within 2 ms of a change (the check ran at SCHED_FIFO 1 there; at normal scheduling it held
the lock while preempted, which was worse). :class:`CheckProcess` runs it in a child process
instead: a fresh interpreter (``python -m pdsmc_ros.controller.sidecar.gain_check``: no rclpy,
none of the parent's threads or locks; :mod:`.process`) at normal scheduling, which builds the
run's reference once and answers each check over its standard input and output (:mod:`.framing`'s
frames); the thread that asks waits on the pipe, without the lock. Lockstep controllers, which
have no deadline, check in their own process (:func:`checked`). ROS-free.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import select
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, cast

from ...control.stability import check_rate
from ...errors import ConfigError, PdsmcError
from ...robots.registry import find_robot, register_robot, robot_config
from ...runs.builder import RunSpec
from .framing import FrameReader, frame, write_all
from .process import as_child, kill, spawn, stopped

WATCH_S = 0.1
"""How often a check waiting for its answer looks whether the child was stopped."""
CHECK_TIMEOUT_S = 30.0
"""How long a gain change waits for the check process (a check started with the child includes its
start and the reference: ~1 s here, 5.6 s under a storm of goals) before the change is refused and
the process replaced."""


def checked(check: Callable[[RunSpec], object], spec: RunSpec) -> None:
    """``check(spec)`` (the stability check); anything it raises besides the package's own errors
    (a ``LinAlgError`` of gains of 1e308) a ConfigError naming the gains: at start-up a one-line
    error, on a set a refusal."""
    try:
        check(spec)
    except PdsmcError:
        raise
    except Exception as exc:  # noqa: BLE001 - numpy's, numba's: what the check could not foresee
        raise ConfigError(f"gains {spec.gains.as_dict()} cannot be checked for stability "
                          f"({type(exc).__name__}: {exc})") from None


class CheckProcess:
    """``check(spec)`` for run-time gain changes, computed in a child process.

    Parameters
    ----------
    spec : RunSpec
        The running run; its reference is the one every check is made along.
    stability : dict
        :func:`~pdsmc_ros.control.stability.check_rate`'s keywords (mode, delay, margin, entry).
    timeout_s : float
        A check not answered in this time is a refusal; the child is killed and replaced.

    The child starts with :meth:`start` or at the first check, and ends with :meth:`close`, or by
    itself when its input closes (the parent is gone); a child that died is started again at the
    next check.
    """

    def __init__(self, spec: RunSpec, stability: dict[str, Any], *, timeout_s: float = CHECK_TIMEOUT_S) -> None:
        if not timeout_s > 0:
            raise ValueError(f"timeout_s must be > 0, got {timeout_s!r}")
        self.spec = spec
        self.stability = dict(stability)
        self.timeout_s = float(timeout_s)
        # the child's start: the run, the check's keywords and the arm as registered here (a URDF arm
        # named, given as a path or received on /robot_description is registered in-process)
        arm = find_robot(spec.robot), dict(robot_config(spec.robot))
        self.first_message = frame((spec, self.stability, *arm))
        self.lock = threading.Lock()  # one check at a time on the pipe
        self.process: subprocess.Popen[bytes] | None = None
        self.answers: FrameReader | None = None  # the child's output, read without waiting

    @classmethod
    def for_run(cls, spec: RunSpec, stability: dict[str, Any]) -> CheckProcess | None:
        """A check process for the run, or None when its arm cannot be sent to one (a robot class
        defined where a child cannot import it): the caller then checks in its own process."""
        try:
            return cls(spec, stability)
        except (pickle.PicklingError, AttributeError, TypeError):
            return None

    def __call__(self, spec: RunSpec) -> None:
        """Raise :class:`ConfigError` with the reason when ``spec``'s gains are refused."""
        with self.lock:
            try:
                process = self._started()
                _send(process, spec)
                reply = _receive(process, self.answers, self.timeout_s)
            except (OSError, EOFError, TimeoutError, pickle.UnpicklingError) as exc:
                self._stop()
                with contextlib.suppress(OSError):
                    self._started()  # replaced now: the next change does not wait for a start
                raise ConfigError(f"gains {spec.gains.as_dict()} refused: the stability check process "
                                  f"failed ({type(exc).__name__}: {exc}); a new one is starting") from None
        if reply is not None:
            raise ConfigError(str(reply))

    def start(self) -> None:
        """Start the child now (it builds the reference while the caller goes on), so the first
        change does not wait for an interpreter's start: under a storm of goals on this machine
        that first check took 5.6 s, later ones 0.1-0.6 s."""
        with self.lock:
            self._started()

    @property
    def pid(self) -> int | None:
        """The child's process id (None before it starts)."""
        process = self.process
        return None if process is None else process.pid

    def _started(self) -> subprocess.Popen[bytes]:
        if self.process is None or self.process.poll() is not None:
            self._stop()
            self.process = spawn(__name__)  # stdout is the answers' pipe; its stderr is the node's (its log)
            if self.process.stdin is None or self.process.stdout is None:  # pragma: no cover - started with pipes
                raise OSError("no pipes to the check process")
            os.set_blocking(self.process.stdout.fileno(), False)
            self.answers = FrameReader(self.process.stdout.fileno())
            self.process.stdin.write(self.first_message)
            self.process.stdin.flush()
        return self.process

    def _stop(self) -> None:
        process, self.process = self.process, None
        if process is not None:
            kill(process, 5.0)

    def close(self) -> None:
        """End the child, if it started."""
        with self.lock:
            self._stop()


def _send(process: subprocess.Popen[bytes], obj: object) -> None:
    if process.stdin is None:  # pragma: no cover - started with a pipe
        raise OSError("no pipe to the check process")
    process.stdin.write(frame(obj))
    process.stdin.flush()


def _receive(process: subprocess.Popen[bytes], answers: FrameReader | None, timeout_s: float) -> object:
    if answers is None:  # pragma: no cover - set with the process
        raise OSError("no pipe from the check process")
    deadline = time.monotonic() + timeout_s
    while True:
        left = deadline - time.monotonic()
        if left <= 0.0:
            raise TimeoutError(f"no answer in {timeout_s:g} s")
        # waits without the interpreter's lock, looking now and then whether the child was stopped
        ready, _, _ = select.select([answers.fd], [], [], min(left, WATCH_S))
        if ready:
            replies = answers.read()
            if replies:
                return replies[0]  # one question at a time: one answer
            if answers.closed:
                raise EOFError("the check process ended")
            continue  # part of the answer: the rest follows
        if stopped(process.pid):
            raise TimeoutError("the process is stopped (SIGSTOP): it would not answer")


def main() -> None:
    """The child: the run and the check's keywords first, then for each spec received ``None``
    (stable) or the refusal's text, until its input closes."""
    as_child()
    requests, out = FrameReader(sys.stdin.fileno()), sys.stdout.fileno()
    waiting = requests.read_blocking()
    if not waiting:
        return
    spec, stability, arm, config = cast(tuple[RunSpec, dict[str, Any], Any, dict[str, Any]], waiting.pop(0))
    if arm is not None and find_robot(spec.robot) is None:
        register_robot(arm, config=config)
    reference = spec.reference()
    while True:
        if not waiting:
            waiting = requests.read_blocking()
            if not waiting:
                return  # the parent is gone
        new = cast(RunSpec, waiting.pop(0))
        try:
            checked(lambda s: check_rate(s, reference, **stability), new)
            reply = None
        except PdsmcError as exc:
            reply = str(exc)
        with contextlib.suppress(OSError):  # the parent gone: the next read ends this process
            write_all(out, frame(reply))


if __name__ == "__main__":
    main()
