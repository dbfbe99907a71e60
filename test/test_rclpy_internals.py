"""rclpy's private names, used in one module (pdsmc_ros/rclpy_internals.py) that says when it breaks."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

rclpy = pytest.importorskip("rclpy")

from pdsmc_ros import rclpy_internals  # noqa: E402

PACKAGE = Path(__file__).resolve().parent.parent / "pdsmc_ros"
PRIVATE = re.compile(r"implementation_singleton|\._parameter_overrides\b|\bnode\._parameters\b|"
                     r"_parameter_event_publisher|rcl_publish_serialized_message|service_take_request|"
                     r"take_message|publish_raw|clear_entities|add_guard_condition|trigger_guard_condition|"
                     r"destroy_when_not_in_use|\bWaitSet\b|\bGuardCondition\b")
"""How a private rclpy, rcl or rmw name reads in the package's source."""


def test_the_installed_rclpy_has_every_private_name_the_package_uses() -> None:
    rclpy.init()
    try:
        node = rclpy.create_node("rclpy_internals_check")
        try:
            lacking = rclpy_internals.missing(node)
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown()
    assert not lacking, (
        f"pdsmc_ros/rclpy_internals.py was written against rclpy {rclpy_internals.WRITTEN_AGAINST}; the installed "
        f"rclpy {rclpy_internals.installed_version()} lacks {', '.join(lacking)}: update that module (and only it)")


def test_the_check_names_what_is_missing(monkeypatch: pytest.MonkeyPatch) -> None:
    """A name gone from rclpy is reported by its holder and name (the check can fail)."""
    monkeypatch.setitem(rclpy_internals.USED, "rclpy.impl.implementation_singleton.rclpy_implementation",
                        ("WaitSet", "no_such_function"))
    assert rclpy_internals.missing() == ["rclpy.impl.implementation_singleton.rclpy_implementation.no_such_function"]


def test_a_declared_but_unset_parameter_reads_none_through_the_public_api() -> None:
    rclpy.init()
    try:
        node = rclpy.create_node("rclpy_internals_values")
        try:
            node.declare_parameter("unset", rclpy.Parameter.Type.DOUBLE_ARRAY)
            node.declare_parameter("set", 2.0)
            assert rclpy_internals.declared_value(node, "unset") is None
            assert rclpy_internals.declared_value(node, "set") == 2.0
            assert rclpy_internals.declared_value(node, "undeclared") is None
            assert rclpy_internals.parameter_overrides(node) == {}
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown()


def test_no_other_module_uses_a_private_rclpy_name() -> None:
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        relative = path.relative_to(PACKAGE).as_posix()
        if relative == "rclpy_internals.py":
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if PRIVATE.search(line):
                found.append(f"  pdsmc_ros/{relative}:{number}: {line.strip()}")
    assert not found, "private rclpy names outside pdsmc_ros/rclpy_internals.py:\n" + "\n".join(found)
