"""A node's status reports: every severity from the one reporting function (rclpy refuses a
second severity from the same line of code, which once killed the plant on a rejected effort)."""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.node import Node  # noqa: E402

from pdsmc_ros.ros.diagnostics import Diagnostics, log  # noqa: E402


@pytest.fixture
def node(rclpy_node: Node) -> Node:
    return rclpy_node


def test_every_severity_in_any_order_from_one_node(node: Node) -> None:
    diagnostics = Diagnostics(node, "test", "hw", values=lambda: {"step": "3"})
    for level in ("warn", "error", "info", "warn", "info", "error"):
        diagnostics.report(level, f"a {level} report")
        log(node, level, f"a {level} line")
