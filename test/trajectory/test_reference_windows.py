"""ReferenceWindows (pdsmc_ros/trajectory/reference_windows.py): every step's bytes are the one-by-one
encoder's, whether its window was serialized on demand or ahead in pieces of spare time."""

from __future__ import annotations

import numpy as np

from pdsmc_ros.bag.cdr import encode_joint_trajectory
from pdsmc_ros.bag.stamps import step_stamp
from pdsmc_ros.trajectory import reference_windows as rw

RATE = 1000.0
NAMES = ("shoulder", "elbow")


def references(steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(steps) / RATE
    q = np.column_stack([np.sin(t), np.cos(2 * t)])
    return q, np.gradient(q, axis=0) * RATE, np.zeros_like(q)


def one_by_one(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, step: int) -> bytes:
    sec, nanosec = step_stamp(step, RATE)
    return encode_joint_trajectory(sec, nanosec, NAMES, q[step].tolist(), qd[step].tolist(), qdd[step].tolist())


class Clock:
    """A clock that advances by ``tick`` every reading: ``ahead`` gets a known number of pieces."""

    def __init__(self, tick: float) -> None:
        self.now, self.tick = 0.0, tick

    def __call__(self) -> float:
        self.now += self.tick
        return self.now


def test_steps_read_in_order_with_pieces_ahead_are_the_encoders_bytes() -> None:
    steps = 2 * rw.ENCODE_WINDOW + 300
    q, qd, qdd = references(steps)
    windows = rw.ReferenceWindows(q, qd, qdd, NAMES, RATE)
    # the first window is serialized when the windows are made, before any loop reads them
    assert len(windows.window) == rw.ENCODE_WINDOW and windows.window_start == 0
    sizes = []
    encode = windows.encode
    windows.encode = lambda start, end: sizes.append(end - start) or encode(start, end)  # type: ignore[method-assign]
    clock = Clock(1e-6)
    pieces_ahead = []
    for step in range(steps):
        assert windows[step] == one_by_one(q, qd, qdd, step), step
        if step % 50 == 0:  # spare time for three pieces now and then
            before = len(windows.ahead)
            windows.encode_ahead(clock.now + rw.PIECE_S + 3e-6 + 1e-9, clock)
            pieces_ahead.append(len(windows.ahead) - before)
    # the pieces reached the next window before it was needed: no window was serialized on demand
    assert max(pieces_ahead) == 3 * rw.ENCODE_PIECE and windows.window_start == 2 * rw.ENCODE_WINDOW
    assert set(sizes) <= {rw.ENCODE_PIECE, 300 % rw.ENCODE_PIECE}


def test_no_spare_time_encodes_nothing_ahead_and_a_jump_is_served_on_demand() -> None:
    q, qd, qdd = references(3 * rw.ENCODE_WINDOW)
    windows = rw.ReferenceWindows(q, qd, qdd, NAMES, RATE)
    assert windows[0] == one_by_one(q, qd, qdd, 0)
    windows.encode_ahead(rw.PIECE_S * 0.5, Clock(0.0))
    assert windows.ahead == []
    windows.encode_ahead(1.0, Clock(0.0))  # time for the whole next window
    assert len(windows.ahead) == rw.ENCODE_WINDOW
    far = 2 * rw.ENCODE_WINDOW + 17  # beyond what was serialized ahead: the clock jumped
    assert windows[far] == one_by_one(q, qd, qdd, far) and windows.ahead == []
    last = 3 * rw.ENCODE_WINDOW - 1
    windows.encode_ahead(1.0, Clock(0.0))  # ahead stops at the run's last step
    assert windows[last] == one_by_one(q, qd, qdd, last)
