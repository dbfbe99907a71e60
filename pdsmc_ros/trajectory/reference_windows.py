"""A run's references serialized a window at a time, the next window ahead in spare time.

The trajectory node publishes one serialized ``JointTrajectory`` a control step.
Serializing one costs about 6 us; a window of them at once with numpy about 1 us each
(:func:`~pdsmc_ros.bag.cdr.encode_joint_trajectories`). In real time a whole window in
one tick made that tick about 1 ms long every :data:`ENCODE_WINDOW` periods -- in a
composed process the controller's next period was late by as much; the next window is
therefore serialized ahead, a piece at a time, in the loop's spare time
(:meth:`ReferenceWindows.encode_ahead`), and only a step the pieces have not reached
yet is serialized on demand.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

from ..bag.cdr import encode_joint_trajectories
from ..bag.stamps import step_stamp
from ..robots.base import FloatArray

ENCODE_WINDOW = 1024
"""References serialized at a time."""
ENCODE_PIECE = 64
"""References serialized ahead in one piece of spare time."""
PIECE_S = 150e-6
"""Spare time a piece needs (about 1 us a reference, with room)."""


class ReferenceWindows:
    """The serialized reference of each step of a run (``windows[step]``).

    Parameters
    ----------
    q, qd, qdd : ndarray, shape (N + 1, n)
        The references at the control steps ``0..N``.
    names : sequence of str
        The joints' names.
    rate : float
        The control rate, Hz (a step's stamp is ``step / rate``).
    """

    def __init__(self, q: FloatArray, qd: FloatArray, qdd: FloatArray, names: Sequence[str], rate: float) -> None:
        self.q, self.qd, self.qdd = q, qd, qdd
        self.names = list(names)
        self.rate = float(rate)
        self.steps = len(q)  # steps 0 .. steps - 1
        self.window_start = 0
        # the first window now, before any loop runs: serialized in the first tick, it made that
        # tick longer than a period and the controller's first command late in a composed process
        self.window: list[bytes] = self.encode(0, min(ENCODE_WINDOW, self.steps))
        self.ahead: list[bytes] = []  # the next window's first references, serialized in spare time

    def encode(self, start: int, end: int) -> list[bytes]:
        """The serialized references of steps ``start`` to ``end - 1``."""
        rows = slice(start, end)
        return encode_joint_trajectories([step_stamp(k, self.rate) for k in range(start, end)], self.names,
                                         self.q[rows], self.qd[rows], self.qdd[rows])

    def __getitem__(self, step: int) -> bytes:
        index = step - self.window_start
        if not 0 <= index < len(self.window):
            ahead_start = self.window_start + len(self.window)
            if ahead_start <= step < ahead_start + len(self.ahead):
                self.window, self.window_start = self.ahead, ahead_start
            else:
                self.window, self.window_start = self.encode(step, min(step + ENCODE_WINDOW, self.steps)), step
            self.ahead = []
            index = step - self.window_start
        return self.window[index]

    def encode_ahead(self, until: float, clock: Callable[[], float] = time.perf_counter) -> None:
        """Serialize the window after the current one, :data:`ENCODE_PIECE` references at a time,
        while ``clock()`` leaves :data:`PIECE_S` before ``until``."""
        start = self.window_start + len(self.window)
        while len(self.ahead) < ENCODE_WINDOW and clock() + PIECE_S < until:
            begin = start + len(self.ahead)
            end = min(begin + ENCODE_PIECE, start + ENCODE_WINDOW, self.steps)
            if begin >= end:
                return
            self.ahead += self.encode(begin, end)
