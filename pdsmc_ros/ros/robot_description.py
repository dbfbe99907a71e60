"""The arm a node is given on ``/robot_description``."""

from __future__ import annotations

from rclpy.node import Node

from ..errors import ConfigError
from ..robots.catalog import ROBOT_DESCRIPTION

ROBOT_DESCRIPTION_WAIT_S = 60.0
"""How long a node given ``robot:=/robot_description`` waits for it (a node composed before the
plant that publishes it would wait in vain: run such nodes in their own processes)."""


def receive_robot_description(node: Node, timeout_s: float = ROBOT_DESCRIPTION_WAIT_S) -> str:
    """The URDF on ``/robot_description`` (transient local, as robot_state_publisher offers it).

    Raises
    ------
    ConfigError
        If none arrives within ``timeout_s``.
    """
    import time

    import rclpy
    from std_msgs.msg import String

    from .topics import LATCHED_QOS, TOPIC_ROBOT_DESCRIPTION

    received: list[str] = []
    subscription = node.create_subscription(String, TOPIC_ROBOT_DESCRIPTION, lambda msg: received.append(msg.data),
                                            LATCHED_QOS)
    node.get_logger().info(f"waiting for the arm on {ROBOT_DESCRIPTION}")
    deadline = time.monotonic() + timeout_s
    try:
        while not received and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        node.destroy_subscription(subscription)
    if not received:
        raise ConfigError(f"{ROBOT_DESCRIPTION}: nothing received within {timeout_s:g} s (is a "
                          "robot_state_publisher or a pdsmc_ros plant running?)")
    return received[-1]
