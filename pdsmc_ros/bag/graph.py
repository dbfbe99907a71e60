"""Bags of a graph the recorder did not start (its graph mode, or ``ros2 bag record``), read back.

A real arm's run: a driver's ``sensor_msgs/JointState`` topic, a controller's
``control_msgs/JointTrajectoryControllerState``, a ``FollowJointTrajectory`` action's status,
feedback and results (the latter as ``get_result`` service events), its accepted goals'
trajectories (``send_goal`` service events, which the project's controller publishes),
``/robot_description``, and where the MuJoCo stand-in ran, its exact state beside what it
published (``/mujoco_driver/true_joint_states``: a joint-state topic whose name ends in
:data:`TRUTH_SUFFIX`).
Topics are found by their types, not their names (a driver may publish on
``/joint_states`` or elsewhere; a controller has a name of its own). ROS-free: the bag's own
message definitions decode it (rosbags); the joint states, by far the most messages, with
:mod:`pdsmc_ros.bag.cdr`'s fast decoder. Times are the messages' header stamps (the clock of the
node that sent them); a goal's end, which no stamp carries, is the receive time of the first
status that shows it ended, moved onto the stamps' clock by the joint states' median offset.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import BagError, CdrError
from ..robots.base import FloatArray
from .cdr import decode_joint_state_named, decode_string

RECORDING_KEY = "pdsmc_ros.recording"
"""``metadata.yaml`` custom data of a graph recording: JSON of its topics, types and counts."""

JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
TRUTH_SUFFIX = "/true_joint_states"
"""A joint-state topic of the true state beside the measured one (the MuJoCo stand-in's ``~/true_joint_states``)."""
CONTROLLER_STATE_TYPE = "control_msgs/msg/JointTrajectoryControllerState"
STATUS_TYPE = "action_msgs/msg/GoalStatusArray"
FEEDBACK_SUFFIX = "FollowJointTrajectory_FeedbackMessage"
RESULT_EVENT_SUFFIX = "FollowJointTrajectory_GetResult_Event"
GOAL_EVENT_SUFFIX = "FollowJointTrajectory_SendGoal_Event"
STATUS_NAMES = {0: "UNKNOWN", 1: "ACCEPTED", 2: "EXECUTING", 3: "CANCELING", 4: "SUCCEEDED", 5: "CANCELED",
                6: "ABORTED"}
TERMINAL = (4, 5, 6)
RESULT_CODES = {0: "SUCCESSFUL", -1: "INVALID_GOAL", -2: "INVALID_JOINTS", -3: "OLD_HEADER_TIMESTAMP",
                -4: "PATH_TOLERANCE_VIOLATED", -5: "GOAL_TOLERANCE_VIOLATED"}
"""control_msgs/action/FollowJointTrajectory's result codes."""


@dataclass
class ReferenceSamples:
    """A controller's desired state over time, in the arm's joint order (``t`` s, ``q`` rad, ``qd`` rad/s)."""

    t: FloatArray
    q: FloatArray
    qd: FloatArray

    @classmethod
    def empty(cls, n: int) -> ReferenceSamples:
        return cls(np.empty(0), np.empty((0, n)), np.empty((0, n)))


@dataclass
class GoalRecord:
    """One action goal as the bag shows it."""

    action: str
    goal_id: str  # the UUID, hex
    accepted: float  # the server's acceptance stamp (s from the run's origin)
    ended: float | None = None  # when a status first showed it ended (stamps' clock, from the origin), s
    status: int = 0  # the last status seen
    error_code: int | None = None  # from the recorded result, if any
    error_string: str = ""
    desired: ReferenceSamples | None = None  # the feedback's desired states
    trajectory: ReferenceSamples | None = None  # the goal's points (from its send_goal event), times from acceptance
    trajectory_points: int | None = None  # how many points the goal's trajectory has, if recorded

    @property
    def status_name(self) -> str:
        return STATUS_NAMES.get(self.status, str(self.status))

    @property
    def result_name(self) -> str:
        if self.error_code is None:
            return "not recorded"
        return RESULT_CODES.get(self.error_code, str(self.error_code))


@dataclass
class GraphRun:
    """The signals of a graph recording, each joint in the order of ``names`` (the arm's, if known)."""

    path: Path
    topics: dict[str, str]  # topic -> type
    counts: dict[str, int]
    state_topic: str
    names: list[str]
    t: FloatArray  # joint-state stamps (s from ``origin``), sorted
    q: FloatArray
    qd: FloatArray
    effort: FloatArray
    reference: ReferenceSamples  # the controller's ~/controller_state reference
    goals: list[GoalRecord] = field(default_factory=list)
    urdf: str | None = None
    truncated: bool = False
    origin: float = 0.0  # the first joint state's stamp (s): every time here counts from it
    truth_topic: str = ""  # the true state's topic, if the bag has one (:data:`TRUTH_SUFFIX`)
    truth_t: FloatArray = field(default_factory=lambda: np.zeros(0))  # its stamps (s from ``origin``)
    truth_q: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))  # its positions, ``names`` order


def deserialize(typestore: Any, data: bytes, type_name: str) -> tuple[Any, int]:
    """A CDR message of ``type_name`` and the length of its bytes, trailing bytes allowed.

    rosbags' own ``deserialize_cdr`` refuses bytes beyond the message's end; rclpy's
    ``serialize_message`` in these wheels returns some for messages with a nested
    ``builtin_interfaces/Duration`` (a ``JointTrajectoryPoint``: 16 stray bytes), and any ROS 2
    reader ignores them. ValueError (or rosbags' errors) if the message itself is malformed.
    """
    if len(data) < 4 or data[:2] not in (b"\x00\x00", b"\x00\x01"):
        raise ValueError(f"not a CDR message of {type_name!r}")
    msgdef = typestore.get_msgdef(type_name)
    decode = msgdef.deserialize_cdr_le if data[1] else msgdef.deserialize_cdr_be
    message, end = decode(memoryview(data)[4:], 0, msgdef.cls, typestore)
    return message, 4 + end


def _topics_of(reader: Any) -> dict[str, str]:
    return {c.topic: c.msgtype for c in reader.connections}


def _columns(names: Sequence[str], order: Sequence[str], values: Sequence[float]) -> list[float]:
    index = {name: i for i, name in enumerate(names)}
    return [float(values[index[j]]) if j in index and index[j] < len(values) else np.nan for j in order]


def _stamp(header: Any) -> int:
    """A header's (or a GoalInfo's) stamp in nanoseconds: whole, so that a wall-clock epoch keeps
    its nanoseconds (as seconds in a float it keeps about a quarter of a microsecond)."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def is_graph_bag(path: str | Path) -> bool:
    """Whether the bag at ``path`` holds a joint-state topic and no run description of the
    project's own pipeline (that analysis reads :mod:`.reader`)."""
    try:
        topics = list_topics(path)
    except BagError:
        return False
    return JOINT_STATE_TYPE in topics.values() and not {"/pdsmc/run_description",
                                                        "/pdsmc/recorder_description"} & set(topics)


def list_topics(path: str | Path) -> dict[str, str]:
    """Topic -> type of the bag at ``path`` (BagError if it cannot be read)."""
    from rosbags.highlevel import AnyReader

    try:
        with AnyReader([Path(path)]) as reader:
            return _topics_of(reader)
    except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds for an unreadable bag
        raise BagError(f"cannot read bag {str(path)!r}: {exc}") from None


def _state_topic(topics: dict[str, str]) -> str:
    found = sorted(t for t, kind in topics.items() if kind == JOINT_STATE_TYPE and not t.endswith(TRUTH_SUFFIX))
    found = found or sorted(t for t, kind in topics.items() if kind == JOINT_STATE_TYPE)
    if not found:
        raise BagError("no sensor_msgs/msg/JointState topic")
    return "/joint_states" if "/joint_states" in found else found[0]


def read_graph_run(path: str | Path, *, joints: Sequence[str] | None = None) -> GraphRun:
    """Read a graph recording; ``joints``: the arm's joints in its order (default: those of the
    first joint state, in its order; a joint a message lacks is NaN there).

    Raises
    ------
    BagError
        If the bag cannot be read or holds no joint states.
    """
    from rosbags.highlevel import AnyReader

    path = Path(path)
    if not path.exists():
        raise BagError(f"bag {str(path)!r} does not exist")
    try:
        reader_cm = AnyReader([path])
        reader = reader_cm.__enter__()
    except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds for an unreadable bag
        raise BagError(f"cannot read bag {str(path)!r}: {exc}") from None
    try:
        return _read(path, reader, joints)
    finally:
        reader_cm.__exit__(None, None, None)


def _read(path: Path, reader: Any, joints: Sequence[str] | None) -> GraphRun:
    topics = _topics_of(reader)
    try:
        state_topic = _state_topic(topics)
    except BagError as exc:
        raise BagError(f"bag {str(path)!r}: {exc}") from None
    counts = {c.topic: c.msgcount for c in reader.connections}
    truth_topic = next((t for t in sorted(topics) if topics[t] == JOINT_STATE_TYPE and t.endswith(TRUTH_SUFFIX)
                        and t != state_topic), "")
    truth_rows: list[tuple[int, tuple[str, ...], Sequence[float]]] = []
    rows: list[tuple[int, int, tuple[str, ...], Sequence[float], Sequence[float], Sequence[float]]] = []
    urdf = None
    status_msgs: list[tuple[str, int, Any]] = []
    feedback: list[tuple[str, Any]] = []
    results: list[tuple[str, Any]] = []
    sent_goals: list[tuple[str, Any]] = []
    reference_rows: list[tuple[int, tuple[str, ...], Any, Any]] = []
    wanted = [c for c in reader.connections if c.topic in (state_topic, truth_topic, "/robot_description")
              or c.msgtype in (CONTROLLER_STATE_TYPE, STATUS_TYPE) or c.msgtype.endswith(FEEDBACK_SUFFIX)
              or c.msgtype.endswith(RESULT_EVENT_SUFFIX) or c.msgtype.endswith(GOAL_EVENT_SUFFIX)]
    for conn, log_ns, raw in reader.messages(connections=wanted):
        data = bytes(raw)
        try:
            if conn.topic == state_topic:
                names, sec, nanosec, position, velocity, torque = decode_joint_state_named(data)
                rows.append((sec * 1_000_000_000 + nanosec, log_ns, tuple(names), position, velocity, torque))
                continue
            if conn.topic == truth_topic:
                names, sec, nanosec, position, _, _ = decode_joint_state_named(data)
                truth_rows.append((sec * 1_000_000_000 + nanosec, tuple(names), position))
                continue
            if conn.topic == "/robot_description":
                urdf = decode_string(data)
                continue
        except CdrError:
            continue  # a malformed message: the bag keeps it as received
        try:
            msg: Any = deserialize(reader.typestore, data, conn.msgtype)[0]
        except Exception:  # noqa: BLE001, S112 - a malformed message is skipped as above
            continue
        action = conn.topic.rsplit("/_action/", 1)[0]
        if conn.msgtype == CONTROLLER_STATE_TYPE:
            reference_rows.append((_stamp(msg.header), tuple(msg.joint_names), msg.reference.positions,
                                   msg.reference.velocities))
        elif conn.msgtype == STATUS_TYPE:
            status_msgs.append((action, log_ns, msg))
        elif conn.msgtype.endswith(FEEDBACK_SUFFIX):
            feedback.append((action, msg))
        elif conn.msgtype.endswith(GOAL_EVENT_SUFFIX):
            sent_goals.append((action, msg))
        else:
            results.append((action, msg))
    if not rows:
        raise BagError(f"bag {str(path)!r} holds no joint states on {state_topic}")
    rows.sort(key=lambda r: r[0])
    order = list(joints) if joints is not None else list(rows[0][2])
    origin = rows[0][0]
    t = np.array([(r[0] - origin) * 1e-9 for r in rows])
    q = np.array([_columns(r[2], order, r[3]) for r in rows])
    qd = np.array([_columns(r[2], order, r[4]) for r in rows])
    effort = np.array([_columns(r[2], order, r[5]) for r in rows])
    # stamps' clock = receive time - offset (the middle of the joint states' delays)
    offset = int(np.median(np.array([r[1] - r[0] for r in rows])))
    reference = _samples([((s - origin) * 1e-9, names, p, v) for s, names, p, v in reference_rows], order)
    goals = _goals(status_msgs, feedback, results, order, origin, offset)
    _goal_trajectories(goals, sent_goals, order)
    truth_rows.sort(key=lambda r: r[0])
    truth_t = np.array([(r[0] - origin) * 1e-9 for r in truth_rows])
    truth_q = np.array([_columns(r[1], order, r[2]) for r in truth_rows]) if truth_rows else np.zeros((0, len(order)))
    return GraphRun(path, topics, counts, state_topic, order, t, q, qd, effort, reference, goals, urdf,
                    origin=origin * 1e-9, truth_topic=truth_topic if truth_rows else "", truth_t=truth_t,
                    truth_q=truth_q)


def _goal_trajectories(goals: Sequence[GoalRecord], events: Sequence[tuple[str, Any]],
                       order: Sequence[str]) -> None:
    """Each goal's trajectory from its ``send_goal`` request event: its points' positions and
    velocities at their ``time_from_start`` (from the goal's acceptance; a trajectory stamped 0
    starts there). Joints the goal does not name are NaN."""
    by_key = {(g.action, g.goal_id): g for g in goals}
    for action, event in events:
        if not len(event.request):
            continue
        request = event.request[0]
        goal = by_key.get((action, bytes(request.goal_id.uuid).hex()))
        if goal is None:
            continue
        trajectory = request.goal.trajectory
        names = tuple(trajectory.joint_names)
        rows = [(goal.accepted + p.time_from_start.sec + p.time_from_start.nanosec * 1e-9, names, p.positions,
                 p.velocities) for p in trajectory.points]
        goal.trajectory_points = len(rows)
        goal.trajectory = _samples(rows, order)


def _samples(rows: Sequence[tuple[float, Sequence[str], Any, Any]], order: Sequence[str]) -> ReferenceSamples:
    rows = sorted((r for r in rows if len(r[2])), key=lambda r: r[0])
    if not rows:
        return ReferenceSamples.empty(len(order))
    t = np.array([r[0] for r in rows])
    q = np.array([_columns(r[1], order, r[2]) for r in rows])
    qd = np.array([_columns(r[1], order, r[3]) if len(r[3]) else [0.0] * len(order) for r in rows])
    return ReferenceSamples(t, q, qd)


def _goals(status_msgs: Sequence[tuple[str, int, Any]], feedback: Sequence[tuple[str, Any]],
           results: Sequence[tuple[str, Any]], order: Sequence[str], origin: int, offset: int) -> list[GoalRecord]:
    goals: dict[tuple[str, str], GoalRecord] = {}
    for action, log_ns, msg in sorted(status_msgs, key=lambda m: m[1]):
        for entry in msg.status_list:
            key = (action, bytes(entry.goal_info.goal_id.uuid).hex())
            goal = goals.get(key)
            if goal is None:
                goal = goals[key] = GoalRecord(action, key[1], (_stamp(entry.goal_info) - origin) * 1e-9)
            goal.status = int(entry.status)
            if goal.status in TERMINAL and goal.ended is None:
                goal.ended = (log_ns - offset - origin) * 1e-9
    by_goal: dict[tuple[str, str], list[tuple[float, Sequence[str], Any, Any]]] = {}
    for action, msg in feedback:
        key = (action, bytes(msg.goal_id.uuid).hex())
        fb = msg.feedback
        by_goal.setdefault(key, []).append(((_stamp(fb.header) - origin) * 1e-9, tuple(fb.joint_names),
                                            fb.desired.positions,
                                            fb.desired.velocities))
    for key, rows in by_goal.items():
        if key in goals:
            goals[key].desired = _samples(rows, order)
    for action, event in results:
        if not len(event.request) or not len(event.response):
            continue
        key = (action, bytes(event.request[0].goal_id.uuid).hex())
        if key in goals:
            response = event.response[0]
            goals[key].error_code = int(response.result.error_code)
            goals[key].error_string = str(response.result.error_string)
            if int(response.status) in TERMINAL:
                goals[key].status = int(response.status)
    return sorted(goals.values(), key=lambda g: g.accepted)
