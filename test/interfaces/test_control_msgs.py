"""control_msgs generated at `make setup` (interfaces/control_msgs, tools/build_interfaces.sh):
the types a client sees on the wire are Jazzy's, and an action goal makes a round trip.

The expected type hashes are computed from the definitions of ros-controls/control_msgs release
5.8.0 (the jazzy branch) with the venv's rosidl_generator_type_description (RIHS01 = SHA-256 of
the type description). MoveIt, `ros2 action send_goal` or a ros2_control stack built against
Jazzy's control_msgs connect only if these are equal.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from conftest import ROOT, next_domain

rclpy = pytest.importorskip("rclpy")

# No importorskip: in a set-up venv control_msgs must import; a skip would hide a broken build.
from builtin_interfaces.msg import Duration  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from control_msgs.msg import JointTolerance, JointTrajectoryControllerState  # noqa: E402
from rclpy.action import ActionClient, ActionServer  # noqa: E402
from rclpy.action.server import ServerGoalHandle  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.task import Future  # noqa: E402
from trajectory_msgs.msg import JointTrajectoryPoint  # noqa: E402

# control_msgs 5.8.0, computed from its definitions (see the module docstring)
FJT_HASH = "RIHS01_738ebcb7a2d7cfa42f9f1001cc99ce3a4383d1cfe508015d9be8485e4b1c66f6"
FJT_FEEDBACK_MESSAGE_HASH = "RIHS01_80398fcb9674a79081a9906e2ccf0c804dd7cb15e22e362e606ee87186beab71"
JTC_STATE_HASH = "RIHS01_51d8dd89cc624cbe9daaeeb4d80d6de9b86168ffdc3be41fefc0953e3c26e480"

DEFINITIONS = (
    "action/FollowJointTrajectory.action",
    "msg/JointTolerance.msg",
    "msg/JointComponentTolerance.msg",
    "msg/JointTrajectoryControllerState.msg",
)

JOINTS = ["joint1", "joint2", "joint3"]


@pytest.fixture
def node() -> Iterator[Node]:
    ctx = Context()
    rclpy.init(context=ctx, domain_id=next_domain())
    created = Node("controller", context=ctx)
    try:
        yield created
    finally:
        created.destroy_node()
        rclpy.shutdown(context=ctx)


def spin_until(executor: SingleThreadedExecutor, done: Callable[[], bool], timeout: float) -> bool:
    """Spin in short slices until `done()` or the timeout (the result says which)."""
    deadline = time.monotonic() + timeout
    while not done():
        if time.monotonic() > deadline:
            return False
        executor.spin_once(timeout_sec=0.05)
    return True


def wire_hashes(node: Node, executor: SingleThreadedExecutor, topic: str) -> list[tuple[str, str]]:
    """(type, type hash) of every publisher the graph shows on `topic` (waits for one)."""
    spin_until(executor, lambda: bool(node.get_publishers_info_by_topic(topic)), 10.0)
    return [(i.topic_type, str(i.topic_type_hash)) for i in node.get_publishers_info_by_topic(topic)]


def test_installed_definitions_are_the_shipped_ones() -> None:
    """The venv's control_msgs was built from interfaces/control_msgs as committed (not stale)."""
    share = Path(sys.prefix) / "share" / "control_msgs"
    for name in DEFINITIONS:
        shipped = (ROOT / "interfaces" / "control_msgs" / name).read_bytes()
        assert (share / name).read_bytes() == shipped, f"{share / name} differs: rerun make setup"


def test_action_feedback_topic_carries_jazzy_type_hash(node: Node) -> None:
    server = ActionServer(node, FollowJointTrajectory, "~/follow_joint_trajectory",
                          execute_callback=lambda handle: FollowJointTrajectory.Result())
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        seen = wire_hashes(node, executor, "/controller/follow_joint_trajectory/_action/feedback")
    finally:
        server.destroy()
        executor.shutdown(timeout_sec=1.0)
    assert seen == [("control_msgs/action/FollowJointTrajectory_FeedbackMessage", FJT_FEEDBACK_MESSAGE_HASH)]


def test_controller_state_topic_carries_jazzy_type_hash(node: Node) -> None:
    node.create_publisher(JointTrajectoryControllerState, "~/controller_state", 10)
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        seen = wire_hashes(node, executor, "/controller/controller_state")
    finally:
        executor.shutdown(timeout_sec=1.0)
    assert seen == [("control_msgs/msg/JointTrajectoryControllerState", JTC_STATE_HASH)]


def test_installed_action_description_has_jazzy_hash() -> None:
    """The action type's own hash (not on any topic) as the generator recorded it."""
    import json

    description = Path(sys.prefix) / "share" / "control_msgs" / "action" / "FollowJointTrajectory.json"
    hashes = {h["type_name"]: h["hash_string"] for h in json.loads(description.read_text())["type_hashes"]}
    assert hashes["control_msgs/action/FollowJointTrajectory"] == FJT_HASH
    assert hashes["control_msgs/action/FollowJointTrajectory_FeedbackMessage"] == FJT_FEEDBACK_MESSAGE_HASH


def test_goal_feedback_and_result_round_trip_in_one_process(node: Node) -> None:
    received_goals: list[FollowJointTrajectory.Goal] = []

    def execute(handle: ServerGoalHandle) -> FollowJointTrajectory.Result:
        goal = handle.request
        received_goals.append(goal)
        feedback = FollowJointTrajectory.Feedback()
        feedback.joint_names = list(goal.trajectory.joint_names)
        feedback.desired = goal.trajectory.points[-1]
        feedback.actual.positions = [0.0] * len(feedback.joint_names)
        feedback.error.positions = list(goal.trajectory.points[-1].positions)
        handle.publish_feedback(feedback)
        handle.abort()
        result = FollowJointTrajectory.Result()
        result.error_code = FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED
        result.error_string = f"{goal.path_tolerance[1].name} beyond {goal.path_tolerance[1].position}"
        return result

    server = ActionServer(node, FollowJointTrajectory, "~/follow_joint_trajectory", execute_callback=execute)
    client = ActionClient(node, FollowJointTrajectory, "/controller/follow_joint_trajectory")
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    feedbacks: list[FollowJointTrajectory.Feedback] = []
    try:
        assert spin_until(executor, client.server_is_ready, 10.0), "the action server never appeared"
        goal = FollowJointTrajectory.Goal()
        goal.trajectory.joint_names = JOINTS
        goal.trajectory.points = [
            JointTrajectoryPoint(positions=[0.1, -0.2, 0.3], time_from_start=Duration(sec=1)),
            JointTrajectoryPoint(positions=[0.4, -0.5, 0.6], velocities=[0.0, 0.0, 0.0],
                                 time_from_start=Duration(sec=2, nanosec=500_000_000)),
        ]
        goal.path_tolerance = [JointTolerance(name=j, position=0.01 * (i + 1)) for i, j in enumerate(JOINTS)]
        goal.goal_tolerance = [JointTolerance(name="joint3", position=0.002, velocity=0.01)]
        goal.goal_time_tolerance = Duration(sec=0, nanosec=250_000_000)
        sent = client.send_goal_async(goal, feedback_callback=lambda msg: feedbacks.append(msg.feedback))
        assert spin_until(executor, sent.done, 10.0), "the goal was never answered"
        handle = sent.result()
        assert handle is not None and handle.accepted
        result_future: Future = handle.get_result_async()
        assert spin_until(executor, result_future.done, 10.0), "no result"
        # feedback is best-effort relative to the result: give a late one a moment
        spin_until(executor, lambda: bool(feedbacks), 2.0)
        response = result_future.result()
    finally:
        client.destroy()
        server.destroy()
        executor.shutdown(timeout_sec=1.0)

    assert received_goals[0] == goal
    assert response is not None
    assert response.status == 6  # action_msgs/GoalStatus.STATUS_ABORTED
    assert response.result.error_code == FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED == -4
    assert response.result.error_string == "joint2 beyond 0.02"
    assert len(feedbacks) == 1
    assert feedbacks[0].joint_names == JOINTS
    assert list(feedbacks[0].desired.positions) == [0.4, -0.5, 0.6]
    assert feedbacks[0].desired.time_from_start == Duration(sec=2, nanosec=500_000_000)
