"""The nodes' start-up: the run their parameters name (declared from the tables by
:func:`~pdsmc_ros.parameters.ros.declare_run_parameters`) as a
:class:`~pdsmc_ros.runs.builder.RunSpec`, the arm of ``/robot_description``; nothing here computes
physics, control or metrics."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node

from ..errors import ConfigError
from ..parameters import BUSY_WAIT, gain_parameters, run_parameters
from ..parameters.ros import declare, declare_run_parameters, value_of
from ..robots.catalog import ROBOT_DESCRIPTION, register_description
from ..runs.builder import RunSpec, run_from_parameters
from .robot_description import receive_robot_description


@dataclass(frozen=True)
class NodeRun:
    """What every node but the controller starts from (the controller's:
    :func:`~pdsmc_ros.controller.parameters.declare_controller_run`): the run its parameters name,
    the mode and the busy-wait; ``values``: every parameter declared so far, by name (None: not set)."""

    spec: RunSpec
    mode: str
    busy_wait: float
    values: dict[str, Any] = dataclasses.field(default_factory=dict)


def declare_node_run(node: Node) -> NodeRun:
    """The start-up lines of every node but the controller: declare the run's parameters, the gains
    (read-only: one params file serves every node; this node runs without them) and ``busy_wait``,
    and build the RunSpec they name (a ConfigError if bad)."""
    values = declare_run_parameters(node)
    values.update(declare(node, (BUSY_WAIT,)))  # used in real time
    take_robot_description(node, values["robot"])
    spec = run_from_parameters(values, needs_gains=False)
    return NodeRun(spec, values["mode"], float(values["busy_wait"]), values)


def take_robot_description(node: Node, robot: str) -> None:
    """``robot:=robot_description``: the arm of the latched ``/robot_description``, registered
    under that name (a ConfigError naming the parameter if none comes or it is not an arm)."""
    if robot == ROBOT_DESCRIPTION:
        try:
            register_description(receive_robot_description(node))
        except ConfigError as exc:
            raise ConfigError(f"parameter robot: {exc}") from None


def run_spec_from_parameters(node: Node, *, needs_gains: bool = True) -> RunSpec:
    """The RunSpec named by the node's declared parameters
    (:func:`~pdsmc_ros.runs.builder.run_from_parameters`)."""
    values = {spec.name: value_of(node, spec.name) for spec in (*run_parameters(), *gain_parameters(applied=False))}
    return run_from_parameters(values, needs_gains=needs_gains)


def description_json(spec: RunSpec, mode: str) -> str:
    data = spec.describe()
    data["mode"] = mode
    return json.dumps(data, sort_keys=True)
