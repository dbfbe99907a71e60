"""Log lines of a control loop, written to the node's logger by its executor, never by the loop's thread."""

from __future__ import annotations

import weakref
from collections import deque
from typing import Any

from rclpy.logging import LoggingSeverity
from rclpy.node import Node

from ..rclpy_internals import rcutils_log

LOOP_LOG_KEPT = 1_000  # lines waiting for the executor at most (more: the oldest are dropped and counted)
_logs: weakref.WeakSet[LoopLog] = weakref.WeakSet()  # this process's loop logs
_looping = False  # a serve loop runs in this process (before and after it, lines are written at once)


class RcutilsLines:
    """A logger's lines written straight to rcutils, as rclpy's logger finally writes them (the
    console and ``/rosout`` alike), without its search for the caller.

    rclpy's ``RcutilsLogger.log`` finds its caller's file, function and line with ``inspect``
    for every line: 0.4 ms of Python here against 6 us for the write itself. In real time the
    executor's thread writes the loop's lines and holds the GIL while it does, which the loop's
    thread waits for. A storm of goals and parameter sets (``bench/storm``) logs about 30
    lines a second. The location written is this module's: the lines come from the loop's
    queue, not from a call site.
    """

    def __init__(self, logger: Any, write: Any) -> None:
        self.logger = logger
        self.write: Any = write  # None once refused: rclpy's own logger from then on

    def _written(self, severity: LoggingSeverity, text: str) -> bool:
        """Whether the line is dealt with here: written, or below the logger's level."""
        if self.write is None:
            return False
        if not self.logger.is_enabled_for(severity):  # as rclpy's logger checks first
            return True
        try:
            self.write(int(severity), self.logger.name, text, "LoopLog.flush", __file__, 0)
        except TypeError:  # an rclpy whose write takes other arguments
            self.write = None
            return False
        return True

    # else rclpy's logger, one call site per severity (it refuses a call site whose severity changes)
    def info(self, text: str) -> None:
        if not self._written(LoggingSeverity.INFO, text):
            self.logger.info(text)

    def warn(self, text: str) -> None:
        if not self._written(LoggingSeverity.WARN, text):
            self.logger.warn(text)

    def error(self, text: str) -> None:
        if not self._written(LoggingSeverity.ERROR, text):
            self.logger.error(text)


def lines_of(logger: Any) -> Any:
    """``logger`` (rclpy's) as :class:`RcutilsLines` where this rclpy offers the write rclpy's own
    logger ends in (a private function: should its arguments change, the lines go through
    ``logger`` again), else ``logger`` itself."""
    write = rcutils_log()
    return logger if write is None else RcutilsLines(logger, write)  # None: another rclpy, its public logger


def loop_running(running: bool) -> None:
    """The serve loop starts (lines are queued from now on) or has ended (every queued line is
    written now, and later lines at once: the executor no longer runs)."""
    global _looping
    _looping = running
    if not running:
        for log in list(_logs):
            log.flush()


class LoopLog:
    """A node's logger for its control loop's thread: a line is queued and the executor writes it.

    rclpy's logger looks up its caller's file for each line (``os.path.realpath``: a system
    call per path part) and takes rclpy's logging mutex; each of those releases the GIL. The
    real-time loop keeps the GIL from the spin before a tick to the tick's end
    (:data:`~.serve.HOLD_SWITCH_S`); once released there, it waits up to that switch
    interval for another thread to hand the GIL back: a line logged in a tick (a hold when a
    goal ends, a torque limited) made that tick milliseconds late. Here the loop only appends
    to a queue and triggers a guard condition; the callback of that guard condition, run by
    the node's executor (a thread of its own in real time, the loop's turns between steps in
    lockstep), writes the lines in order. Safe to call from any thread. Outside the serve loop
    (:func:`loop_running`: start-up, the nodes' ``close``) a line is written at once. Lines go
    to rcutils directly (:class:`RcutilsLines`), which keeps the executor's share of the GIL small.

    Parameters
    ----------
    node : rclpy.node.Node
        The node whose logger writes the lines; it must be spun by an executor.
    """

    def __init__(self, node: Node) -> None:
        self.logger = lines_of(node.get_logger())
        self.lines: deque[tuple[str, str]] = deque()
        self.dropped = 0
        self.wake = node.create_guard_condition(self.flush)
        _logs.add(self)

    def _queue(self, level: str, text: str) -> None:
        if not _looping:
            self.lines.append((level, text))
            self.flush()
            return
        if len(self.lines) >= LOOP_LOG_KEPT:
            self.lines.popleft()
            self.dropped += 1
        self.lines.append((level, text))
        self.wake.trigger()

    def info(self, text: str) -> None:
        self._queue("info", text)

    def warn(self, text: str) -> None:
        self._queue("warn", text)

    def error(self, text: str) -> None:
        self._queue("error", text)

    def flush(self) -> None:
        """Write the queued lines (the executor's callback; also called once the loop has ended)."""
        if self.dropped:
            dropped, self.dropped = self.dropped, 0
            self.logger.warn(f"{dropped} log lines of the control loop dropped (more than {LOOP_LOG_KEPT} "
                             "waited for the executor)")
        while self.lines:
            level, text = self.lines.popleft()
            # one call site per severity: rclpy refuses a call site whose severity changes
            if level == "info":
                self.logger.info(text)
            elif level == "warn":
                self.logger.warn(text)
            else:
                self.logger.error(text)
