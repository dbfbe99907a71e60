"""What each node of the package declares and opens, read from the nodes themselves.

Run as a script (``python docs/hooks/node_interfaces.py [MODE]``) it builds every node the package's
executables start, as ``run_node`` builds it (the wrapper, then its real-time settings), with
rclpy's ``Node`` methods wrapped so that each parameter declaration (name, default, descriptor),
publisher, subscription, service and action server is noted, and prints them as JSON. Nothing
is spun: the nodes are built and dropped. The documentation's node reference
(:mod:`docs.hooks.reference`) is rendered from this output, so it cannot drift from the code.
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
from collections.abc import Callable
from typing import Any

RCLPY_SERVICES = ("describe_parameters", "get_parameter_types", "get_parameters", "list_parameters",
                  "set_parameters", "set_parameters_atomically", "get_type_description")
"""Services rclpy opens on every node (not the package's)."""
RCLPY_TOPICS = ("/parameter_events", "/rosout")


def _plain(value: Any) -> Any:
    """A JSON-able copy of a parameter default (numpy scalars, tuples, inf; a ``Parameter.Type``
    declared without a value: ``None``)."""
    from rclpy.parameter import Parameter

    if isinstance(value, Parameter.Type):
        return None
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if hasattr(value, "item"):
        return value.item()
    return value


def _type_name(msg_type: Any) -> str:
    module = msg_type.__module__.split(".")  # e.g. sensor_msgs.msg._joint_state
    return f"{module[0]}/{module[1]}/{msg_type.__name__}"


def _qos_text(qos: Any) -> str:
    if isinstance(qos, int):
        return f"keep last {qos}"
    parts = []
    history = getattr(qos.history, "name", str(qos.history)).lower()
    parts.append("keep all" if "all" in history else f"keep last {qos.depth}")
    parts.append(getattr(qos.reliability, "name", "").lower().replace("_", " "))
    parts.append(getattr(qos.durability, "name", "").lower().replace("_", " "))
    return ", ".join(p for p in parts if p)


def record(factories: dict[str, Callable[[], Any]], mode: str) -> dict[str, Any]:
    """Build each node wrapper in ``mode`` (lockstep or realtime) and return what every rclpy
    node it made declared and opened."""
    import rclpy
    from rclpy.action import ActionServer
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    from pdsmc_ros.loop.realtime_params import loop_reports

    notes: dict[str, dict[str, Any]] = {}
    current: list[str] = []
    nodes: dict[str, Any] = {}

    def entry(node: Any) -> dict[str, Any]:
        name = node.get_fully_qualified_name()
        nodes[name] = node
        return notes.setdefault(name, {"executable": current[-1] if current else "", "parameters": {},
                                       "publishers": [], "subscriptions": [], "services": [], "actions": []})

    declare = Node.declare_parameter
    publisher = Node.create_publisher
    subscription = Node.create_subscription
    action_init = ActionServer.__init__

    def declare_parameter(self: Any, name: str, value: Any = None, descriptor: Any = None, *args: Any,
                          **kwargs: Any) -> Any:
        result = declare(self, name, value, descriptor, *args, **kwargs)
        info: dict[str, Any] = {"default": _plain(value)}
        if isinstance(value, Parameter.Type):
            info["type"] = value.name.lower()
        if descriptor is not None:
            info["description"] = descriptor.description
            info["constraints"] = descriptor.additional_constraints
            if descriptor.floating_point_range:
                r = descriptor.floating_point_range[0]
                info["range"] = [_plain(r.from_value), _plain(r.to_value)]
            if descriptor.integer_range:
                r = descriptor.integer_range[0]
                info["range"] = [r.from_value, r.to_value]
            info["read_only"] = descriptor.read_only
        entry(self)["parameters"].setdefault(name, info)
        return result

    def create_publisher(self: Any, msg_type: Any, topic: str, qos: Any, *args: Any, **kwargs: Any) -> Any:
        pub = publisher(self, msg_type, topic, qos, *args, **kwargs)
        if pub.topic_name not in RCLPY_TOPICS:
            entry(self)["publishers"].append([pub.topic_name, _type_name(msg_type), _qos_text(qos)])
        return pub

    def create_subscription(self: Any, msg_type: Any, topic: str, callback: Any, qos: Any, *args: Any,
                            **kwargs: Any) -> Any:
        sub = subscription(self, msg_type, topic, callback, qos, *args, **kwargs)
        entry(self)["subscriptions"].append([sub.topic_name, _type_name(msg_type), _qos_text(qos)])
        return sub

    def action_server(self: Any, node: Any, action_type: Any, action_name: str, *args: Any, **kwargs: Any) -> None:
        action_init(self, node, action_type, action_name, *args, **kwargs)
        namespace = node.get_fully_qualified_name() if action_name.startswith("~") else ""
        name = namespace + action_name[1:] if namespace else action_name
        entry(node)["actions"].append([name if name.startswith("/") else "/" + name, _type_name(action_type)])

    Node.declare_parameter = declare_parameter  # type: ignore[method-assign]
    Node.create_publisher = create_publisher  # type: ignore[method-assign]
    Node.create_subscription = create_subscription  # type: ignore[method-assign]
    ActionServer.__init__ = action_server  # type: ignore[method-assign]
    with tempfile.TemporaryDirectory() as tmp:
        # the viewer on any free port, the recorder into a scratch directory: the defaults
        # recorded are the declarations' own, not these overrides
        # in real time the five-bar, whose preset gains pass the real-time stability check
        robot = "parallel_5r" if mode == "realtime" else "serial_3r"
        rclpy.init(args=["--ros-args", "-p", f"mode:={mode}", "-p", f"robot:={robot}", "-p", "viewer:port:=0",
                         "-p", f"recorder:output:={tmp}/bag"])
        for executable, factory in factories.items():
            current.append(executable)
            wrapper = factory()
            loop_reports(wrapper)
    for name, node in nodes.items():  # every service, the lifecycle's (made by rcl, not create_service) too
        notes[name]["services"] = sorted(
            [s.srv_name, _type_name(s.srv_type)] for s in node.services
            if s.srv_name.rsplit("/", 1)[-1] not in RCLPY_SERVICES)
    return notes


def factories() -> dict[str, Callable[[], Any]]:
    """The node wrappers each executable of the package builds (``setup.py``'s console scripts)."""
    from pdsmc_ros.controller.node import ControllerNode
    from pdsmc_ros.mujoco_driver.node import MujocoDriverNode
    from pdsmc_ros.plant.node import PlantNode
    from pdsmc_ros.recorder.node import RecorderNode
    from pdsmc_ros.trajectory.node import TrajectoryNode
    from pdsmc_ros.viewer.node import ViewerNode

    return {"plant": PlantNode, "trajectory": TrajectoryNode, "controller": ControllerNode,
            "recorder": RecorderNode, "viewer": ViewerNode, "mujoco_driver": MujocoDriverNode}


if __name__ == "__main__":
    notes = record(factories(), sys.argv[1] if len(sys.argv) > 1 else "lockstep")
    sys.stdout.write(json.dumps(notes, indent=1) + "\n")  # in declaration order
    sys.stdout.flush()
    os._exit(0)  # the nodes were never spun: skip their teardown
