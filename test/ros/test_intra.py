"""Intra-process delivery between composed nodes (pdsmc_ros.ros.intra)."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest
from conftest import next_domain

rclpy = pytest.importorskip("rclpy")

from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from pdsmc_ros.bag import cdr  # noqa: E402
from pdsmc_ros.loop.inputs import Inputs, take_local  # noqa: E402
from pdsmc_ros.ros import intra  # noqa: E402
from pdsmc_ros.ros.publishers import GuardedPublisher  # noqa: E402
from pdsmc_ros.ros.topics import LATCHED_QOS, LATEST_QOS, LOCKSTEP_QOS, STREAM_QOS  # noqa: E402

DOMAIN_ID = next_domain()  # apart from the other tests


@pytest.fixture
def contexts() -> Iterator[tuple[Context, Context]]:
    """The composed process's context and another one (a second DDS participant, as a
    node in another process would have)."""
    made = []
    for _ in range(2):
        ctx = Context()
        rclpy.init(context=ctx, domain_id=DOMAIN_ID)
        made.append(ctx)
    try:
        yield made[0], made[1]
    finally:
        intra.activate(None)
        for ctx in made:
            ctx.try_shutdown()


def _node(name: str, ctx: Context) -> Node:
    return Node(name, context=ctx, start_parameter_services=False, enable_rosout=False)


def _state(step: int) -> bytes:
    return cdr.encode_joint_state(0, step, ["j1"], [float(step)], [0.0], [0.0])


def _until(condition: Any, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.01)
    return False


def test_local_subscribers_get_every_message_and_dds_only_peers_outside(contexts: tuple) -> None:
    ctx, other = contexts
    domain = intra.IntraProcess(ctx)
    intra.activate(domain)
    plant, controller, trajectory = _node("plant", ctx), _node("controller", ctx), _node("trajectory", ctx)
    got_all: list[bytes] = []
    got_latest: list[bytes] = []
    keep_all = Inputs(controller, "lockstep")
    keep_all.subscribe(JointState, "joint_states", got_all.append, LOCKSTEP_QOS)
    newest = Inputs(trajectory, "realtime")
    newest.subscribe(JointState, "joint_states", got_latest.append, LATEST_QOS)
    not_local = Inputs(controller, "lockstep")
    not_local.subscribe(JointState, "nobody_here_publishes", got_all.append)
    pub = GuardedPublisher(plant.create_publisher(JointState, "joint_states", STREAM_QOS), plant)
    latched = GuardedPublisher(plant.create_publisher(String, "description", LATCHED_QOS), plant)
    intra.activate(None)
    assert domain.bind() == {"/joint_states": 2}

    # the two local inputs have no DDS reader; the one without a local publisher has
    assert keep_all.io_node is None and keep_all.local and newest.local
    assert not_local.io_node is not None and len(not_local.hot) == 1
    assert latched._route is None  # transient-local stays on DDS (late joiners need it)
    assert pub.publisher.get_subscription_count() == 0
    assert pub.get_subscription_count() == 2

    for step in range(5):
        pub.publish(_state(step))
    assert not take_local(not_local.local)
    assert take_local(keep_all.local) and take_local(newest.local)
    assert got_all == [_state(k) for k in range(5)]  # keep-all: every message, in order
    assert got_latest == [_state(4)]  # keep-last 1: the newest, as its DDS reader would

    # a subscriber in another participant is matched: from then on DDS carries the messages
    outside = _node("recorder", other)
    received: list[bytes] = []
    outside.create_subscription(JointState, "joint_states", received.append, LOCKSTEP_QOS, raw=True)
    executor = SingleThreadedExecutor(context=other)
    executor.add_node(outside)
    assert _until(lambda: pub.get_subscription_count() == 3)
    for step in range(5, 8):
        pub.publish(_state(step))
    assert _until(lambda: (executor.spin_once(timeout_sec=0.05), len(received) == 3)[1])
    assert received == [_state(k) for k in range(5, 8)]
    take_local(keep_all.local)
    assert got_all == [_state(k) for k in range(8)]  # each message once, none twice
    executor.shutdown()
    for inputs in (keep_all, newest, not_local):
        inputs.destroy()
    domain.destroy()


def test_subscriptions_after_bind_are_refused(contexts: tuple) -> None:
    ctx, _ = contexts
    domain = intra.IntraProcess(ctx)
    domain.bind()
    with pytest.raises(RuntimeError, match="before bind"):
        domain.add_subscription("/joint_states", JointState, LOCKSTEP_QOS,
                                local=lambda q: None, dds=lambda: None)
    domain.destroy()
