"""A node's status reports: every severity from the one reporting function (rclpy refuses a
second severity from the same line of code, which once killed the plant on a rejected effort)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from conftest import next_domain

rclpy = pytest.importorskip("rclpy")

from rclpy.context import Context  # noqa: E402
from rclpy.node import Node  # noqa: E402

from pdsmc_ros.ros.diagnostics import Diagnostics, log  # noqa: E402

DOMAIN_ID = next_domain()


@pytest.fixture
def node() -> Iterator[Node]:
    ctx = Context()
    rclpy.init(context=ctx, domain_id=DOMAIN_ID)
    created = Node("diagnostics_test", context=ctx)
    try:
        yield created
    finally:
        created.destroy_node()
        rclpy.shutdown(context=ctx)


def test_every_severity_in_any_order_from_one_node(node: Node) -> None:
    diagnostics = Diagnostics(node, "test", "hw", values=lambda: {"step": "3"})
    for level in ("warn", "error", "info", "warn", "info", "error"):
        diagnostics.report(level, f"a {level} report")
        log(node, level, f"a {level} line")
