"""The result of a goal lost with the goal process (:mod:`pdsmc_ros.controller.sidecar.lost_results`), with a
plain rclpy client of the action's ``get_result`` service in this process: a request is kept while
the goal process serves, answered once the goal is told lost, and a lost goal's late request is
answered until a new child serves."""

from __future__ import annotations

import time
import uuid

import pytest
from conftest import next_domain

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("control_msgs")
from action_msgs.msg import GoalStatus  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from unique_identifier_msgs.msg import UUID  # noqa: E402

from pdsmc_ros.controller.goals import INVALID_GOAL, Outcome  # noqa: E402
from pdsmc_ros.controller.sidecar.lost_results import LostResults  # noqa: E402

SERVICE = FollowJointTrajectory.Impl.GetResultService
LOST = Outcome("aborted", INVALID_GOAL, "the goal process ended (killed by SIGKILL): the goal was aborted")


@pytest.fixture
def pair():  # noqa: ANN201
    """The controller's node with its :class:`LostResults`, and a client node asking for results."""
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=next_domain())
    controller = rclpy.create_node("controller", context=context)
    results = LostResults(controller, controller.get_fully_qualified_name())
    client_node = rclpy.create_node("client", context=context)
    client = client_node.create_client(SERVICE, "/controller/follow_joint_trajectory/_action/get_result")
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(client_node)
    assert client.wait_for_service(timeout_sec=10.0)
    yield results, client, executor
    executor.shutdown()
    client_node.destroy_node()
    results.destroy()
    controller.destroy_node()
    rclpy.shutdown(context=context)


def ask(client, key: bytes):  # noqa: ANN001, ANN201
    return client.call_async(SERVICE.Request(goal_id=UUID(uuid=list(key))))


def gathered_until(results: LostResults, executor, done, seconds: float = 3.0) -> int:  # noqa: ANN001
    """Gather (as the watching thread does) and spin the client until ``done()`` or ``seconds``; answers."""
    answered = 0
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and not done():
        answered += results.gather()
        executor.spin_once(timeout_sec=0.02)
    return answered


def test_a_request_is_kept_while_the_goal_runs_and_answered_once_the_goal_is_lost(pair) -> None:  # noqa: ANN001
    results, client, executor = pair
    running, other = uuid.uuid4().bytes, uuid.uuid4().bytes
    future, unrelated = ask(client, running), ask(client, other)
    # the goal process serves: nothing is answered here, however long the requests wait
    assert gathered_until(results, executor, future.done, 1.0) == 0
    assert not future.done() and not unrelated.done()
    assert set(results.waiting) == {running, other}
    results.lose(running, LOST)  # the loop's thread, as the child is lost
    assert gathered_until(results, executor, future.done) == 1
    response = future.result()
    assert response.status == GoalStatus.STATUS_ABORTED
    assert (response.result.error_code, response.result.error_string) == (INVALID_GOAL, LOST.error_string)
    # a goal that was not lost stays the goal process's to answer
    executor.spin_once(timeout_sec=0.2)
    assert not unrelated.done() and other in results.waiting


def test_a_lost_goals_late_request_is_answered_until_a_new_child_serves(pair) -> None:  # noqa: ANN001
    results, client, executor = pair
    lost = uuid.uuid4().bytes
    results.lose(lost, Outcome("succeeded", 0, ""))  # an end the child was told but never answered
    late = ask(client, lost)
    assert gathered_until(results, executor, late.done) == 1
    assert late.result().status == GoalStatus.STATUS_SUCCEEDED
    results.served()  # from here the new child's server answers (rclpy: STATUS_UNKNOWN for a goal it never had)
    later = ask(client, lost)
    assert gathered_until(results, executor, later.done, 1.0) == 0
    assert not later.done()
