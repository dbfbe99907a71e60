"""The goal process's ROS-free parts: a goal pickled to the loop's process drives as the original
would, the pipe's framing never blocks the loop, and the loop's side (:class:`GoalProcess`)
starts, cancels and reports goals as the in-process action server does."""

from __future__ import annotations

import os
import pickle
import time

import numpy as np
import pytest

from pdsmc_ros.bag.cdr import encode_joint_state
from pdsmc_ros.bag.stamps import step_stamp
from pdsmc_ros.controller import goals as g
from pdsmc_ros.controller.commanding import TorqueGuard
from pdsmc_ros.controller.core import ControllerCore
from pdsmc_ros.controller.joint_trajectory import MAX_POINTS
from pdsmc_ros.controller.joints import JointSelector
from pdsmc_ros.controller.limits import JointLimits
from pdsmc_ros.controller.sidecar.framing import STATE_BACKLOG, FrameReader, FrameWriter
from pdsmc_ros.controller.sidecar.goal_process import GoalProcess
from pdsmc_ros.parameters.joint_map import JointMap
from pdsmc_ros.runs.builder import make_run

SPEC = make_run("serial_3r", "circle", "pd")
ROBOT = SPEC.robot_model()
NAMES = tuple(ROBOT.joint_names)


def state(step: int, q: np.ndarray, qd: np.ndarray) -> bytes:
    return encode_joint_state(*step_stamp(step, SPEC.rate), list(NAMES), q.tolist(), qd.tolist(), [])


def make_core() -> ControllerCore:
    made = ControllerCore(SPEC, JointSelector(NAMES), JointMap(NAMES, list(NAMES)), JointLimits.of(ROBOT, NAMES),
                          TorqueGuard(None), 20 / SPEC.rate, False, lambda why: None)
    made.configure()
    made.activate()
    return made


def long_goal(core: ControllerCore, points: int, *, velocities: bool = True) -> g.GoalExecution:
    q0 = core.reference.sample([0.0]).q[0]
    core.add_state(state(0, q0, np.zeros(3)), "joint_states")
    t = np.linspace(0.01, 5.0, points)
    w = np.pi / 5.0  # half a cosine: at rest at both ends
    raw = [((q0 + 0.05 * (1.0 - np.cos(w * s))).tolist(),
            (0.05 * w * np.sin(w * s) * np.ones(3)).tolist() if velocities else [], [],
            int(s), int(round((s % 1.0) * 1e9))) for s in t]
    raw[-1] = (raw[-1][0], [0.0, 0.0, 0.0] if velocities else [], [], 5, 0)
    started = core.check_goal(0.0, NAMES, raw, (), 100.0, [], [], 0.0)
    assert isinstance(started.goal, g.GoalExecution), started.goal
    return started.goal


@pytest.mark.parametrize("velocities", [True, False])
def test_a_goal_pickled_to_the_loop_samples_as_the_original_and_travels_as_arrays(velocities: bool) -> None:
    original = long_goal(make_core(), MAX_POINTS, velocities=velocities)
    data = pickle.dumps(original, protocol=pickle.HIGHEST_PROTOCOL)
    copy = pickle.loads(data)
    assert isinstance(copy.reference.positions, np.ndarray) and copy.reference.positions.shape == (MAX_POINTS, 3)
    assert not copy.done.is_set() and copy.outcome is None
    assert copy.reference.starts_at_first_sample == original.reference.starts_at_first_sample
    for t in np.linspace(-0.1, 5.2, 97):
        for a, b in zip(copy.reference.sample(100.0 + t), original.reference.sample(100.0 + t)):
            np.testing.assert_array_equal(a, b)
    for k in (0, 1, MAX_POINTS // 2, MAX_POINTS - 1):
        for a, b in zip(copy.reference.segment_samples(k, 4), original.reference.segment_samples(k, 4)):
            np.testing.assert_array_equal(a, b)
    # stacked arrays, not 5,000 objects: the pickle is about the size of the values themselves
    values = MAX_POINTS * 8 * (1 + 3 * (2 if velocities else 1))  # the times and the points' values
    assert len(data) < 1.2 * values
    ended = pickle.loads(pickle.dumps(dataclass_finished(original)))
    assert ended.done.is_set() and ended.outcome == g.CANCELED


def dataclass_finished(execution: g.GoalExecution) -> g.GoalExecution:
    execution.finish(g.CANCELED)
    return execution


def test_frames_cross_a_pipe_in_pieces_and_a_full_pipe_never_blocks_the_writer() -> None:
    read_end, write_end = os.pipe()
    os.set_blocking(read_end, False)
    os.set_blocking(write_end, False)
    reader, writer = FrameReader(read_end), FrameWriter(write_end)
    try:
        big = np.arange(400_000, dtype=float)  # 3.2 MB: far beyond a pipe's buffer
        start = time.perf_counter()
        writer.send(("big", big))
        assert time.perf_counter() - start < 5.0  # returned: what did not fit waits in the writer
        assert writer.pending  # the pipe is full
        writer.send(("state", 1), droppable=True)  # dropped: a backlog waits
        assert len(writer.pending) > STATE_BACKLOG
        writer.send(("ended", 2))  # never dropped
        received: list[object] = []
        while writer.pending or not received or received[-1] != ("ended", 2):
            received += reader.read()
            writer.flush()
        assert received[0][0] == "big" and np.array_equal(received[0][1], big)
        assert received[1:] == [("ended", 2)]
        os.close(write_end)
        writer.closed = True
        assert reader.read() == [] and reader.closed
    finally:
        os.close(read_end)
        if not writer.closed:
            os.close(write_end)


class FakeChild:
    """The child's end of the loop's pipes: what the loop's side sends and receives."""

    def __init__(self, process: GoalProcess) -> None:
        to_loop_read, self.to_loop = os.pipe()
        self.from_loop, from_loop_write = os.pipe()
        os.set_blocking(to_loop_read, False)
        os.set_blocking(from_loop_write, False)
        os.set_blocking(self.from_loop, False)
        process.reader, process.writer = FrameReader(to_loop_read), FrameWriter(from_loop_write)
        self.inbox = FrameReader(self.from_loop)
        self.heard: list[tuple] = []

    def send(self, message: object) -> None:
        data = pickle.dumps(message)
        os.write(self.to_loop, len(data).to_bytes(4, "little") + data)

    def hear(self) -> list[tuple]:
        self.heard += self.inbox.read()  # type: ignore[arg-type]
        return self.heard


def test_the_loop_starts_preempts_cancels_and_reports_goals_from_the_child() -> None:
    core = make_core()
    loop = GoalProcess({}, core, lambda: 7)
    child = FakeChild(loop)
    first, second = long_goal(core, 50), long_goal(core, 60)
    child.send(("start", b"A", pickle.loads(pickle.dumps(first))))
    loop.poll(0.0)
    assert core.goals.active is None  # not active yet: refused as joint_trajectory_controller does
    loop.poll(0.01)
    assert ("ended", b"A", g.Outcome("aborted", g.INVALID_GOAL, "the controller is not active")) in child.hear()
    loop.set_active(True)
    child.send(("start", b"B", pickle.loads(pickle.dumps(first))))
    loop.poll(0.1)
    running = core.goals.active
    assert running is not None and running.action
    assert ("active", True) in child.hear()
    assert [m[1] for m in child.heard if m[0] == "driving"] == [b"B"]
    # the period's state and the goal's feedback at the feedback rate, with the clamp count
    tau, _ = core.realtime_command(core.latest.state_time, lambda: 100.2)
    assert tau is not None
    loop.poll(0.2)
    news = [m for m in child.hear() if m[0] == "state"]
    assert news and news[-1][2] == 7 and b"B" in news[-1][3]
    child.send(("start", b"C", pickle.loads(pickle.dumps(second))))
    loop.poll(0.3)
    assert ("ended", b"B", g.PREEMPTED) in child.hear()
    child.send(("cancel", b"C"))
    loop.poll(0.4)
    assert ("ended", b"C", g.CANCELED) in child.hear() and core.goals.active is None
    assert [m for m in child.heard if m[0] == "driving"][-1] == ("driving", None, 0.0, 0.0)  # a hold drives now
    # ~/joint_trajectory, taken by the loop's process as bytes: handed over with its times, in order
    loop.forward([(b"first", (1.0, 2.0)), (memoryview(b"second"), (None, None))])
    assert [m for m in child.hear() if m[0] == "trajectory"] == [("trajectory", b"first", (1.0, 2.0)),
                                                                 ("trajectory", b"second", (None, None))]
