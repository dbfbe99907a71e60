"""A node's status on ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``, recorded in bags)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

from .publishers import GuardedPublisher
from .topics import STREAM_QOS, TOPIC_DIAGNOSTICS

LEVELS = {"info": DiagnosticStatus.OK, "warn": DiagnosticStatus.WARN, "error": DiagnosticStatus.ERROR}


def log(node: Node, level: str, message: str, logger: Any = None) -> None:
    """Log ``message`` at ``level`` (``info``, ``warn``, ``error``) with ``logger`` (default the node's).

    One call site per severity: rclpy refuses a second severity from the same line of code.
    """
    logger = logger if logger is not None else node.get_logger()
    if level == "error":
        logger.error(message)
    elif level == "warn":
        logger.warn(message)
    else:
        logger.info(message)


class Diagnostics:
    """Publishes one status (``name``, ``hardware_id``) with the key-values ``values()`` gives,
    stamped with ``stamp()`` (default: the node's clock), and logs it at its level with ``logger``
    (default: the node's; a node publishing for another, e.g. the action server's, logs as that one)."""

    def __init__(self, node: Node, name: str, hardware_id: str, *,
                 values: Callable[[], dict[str, str]] = dict, stamp: Callable[[], Time] | None = None,
                 logger: Any = None) -> None:
        self.node = node
        self.logger = logger
        self.name = name
        self.hardware_id = hardware_id
        self.values = values
        self.stamp = stamp or (lambda: node.get_clock().now().to_msg())
        self.pub = GuardedPublisher(node.create_publisher(DiagnosticArray, TOPIC_DIAGNOSTICS, STREAM_QOS), node)

    def publish(self, level: str, message: str) -> None:
        """Publish ``message`` at ``level`` (``info``, ``warn``, ``error``) on /diagnostics only."""
        status = DiagnosticStatus(level=LEVELS[level], name=self.name, message=message, hardware_id=self.hardware_id,
                                  values=[KeyValue(key=k, value=v) for k, v in self.values().items()])
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.stamp()
        self.pub.publish(msg)

    def report(self, level: str, message: str) -> None:
        """Log ``message`` at ``level`` and publish it."""
        log(self.node, level, message, self.logger)
        self.publish(level, message)


class InputReport:
    """A node's current problem with its inputs: a throttled error line while it lasts, a
    diagnostic when it changes, and one line when the inputs are complete again."""

    def __init__(self, diagnostics: Diagnostics, *, throttle_s: float = 1.0) -> None:
        self.diagnostics = diagnostics
        self.throttle_s = throttle_s
        self.problem: str | None = None

    def __call__(self, problem: str | None) -> None:
        logger = self.diagnostics.node.get_logger()
        if problem is None:
            if self.problem is not None:
                logger.info("complete inputs again: control resumed")
                self.diagnostics.publish("info", "inputs complete")
                self.problem = None
            return
        if problem != self.problem:
            self.diagnostics.publish("error", problem)
        self.problem = problem
        logger.error(f"{problem}: no torque computed from it", throttle_duration_sec=self.throttle_s)
