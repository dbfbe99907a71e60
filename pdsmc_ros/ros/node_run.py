"""Run parameters of the nodes: declared from the tables (:mod:`pdsmc_ros.parameters`), turned
into a :class:`~pdsmc_ros.runs.builder.RunSpec`; nothing here computes physics, control or metrics."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node

from ..control import law
from ..errors import ConfigError
from ..parameters import BUSY_WAIT, STABILITY, gain_parameters, run_parameters
from ..parameters.ros import declare, guard, value_of
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


def declare_run_parameters(node: Node, *, gains: bool = False) -> dict[str, Any]:
    """Declare the run's parameters and the gains (every node: one params file or ``-p kp:=``
    serves all; only the controller uses them, ``gains``, and it also declares
    :data:`~pdsmc_ros.parameters.STABILITY`), guard them (:func:`~pdsmc_ros.parameters.ros.guard`:
    the gains are the controller's to check, :class:`~pdsmc_ros.controller.parameters.GainUpdates`)
    and return their values."""
    values = declare(node, run_parameters())
    gain_specs = gain_parameters(applied=gains and _law_gains(values["type"]))
    values.update(declare(node, gain_specs, checked=False))  # the resolver's messages name the law
    if gains:
        values.update(declare(node, STABILITY))
    guard_run_parameters(node, values["type"], gains=gains)
    return values


def guard_run_parameters(node: Node, controller: str, *, gains: bool = False) -> None:
    """Guard the run's parameters, the gains of law ``controller`` and (``gains``: the controller)
    the stability parameters on ``node`` (:func:`~pdsmc_ros.parameters.ros.guard`); the gains are
    the controller's to check (:class:`~pdsmc_ros.controller.parameters.GainUpdates`). Also the
    goal process's stand-in of the controller's parameters, declared as the controller's."""
    gain_specs = gain_parameters(applied=gains and _law_gains(controller))
    specs = (*run_parameters(), *gain_specs, *(STABILITY if gains else ()))
    guard(node, specs, checked_by_node=[g.name for g in gain_specs])


def _law_gains(controller: str) -> tuple[str, ...]:
    """The gains ``controller`` needs (the controller applies those at run time); none for an
    unknown law (the run's check names it)."""
    try:
        return law(controller).gain_names
    except ConfigError:
        return ()


def run_spec_from_parameters(node: Node, *, needs_gains: bool = True) -> RunSpec:
    """The RunSpec named by the node's declared parameters
    (:func:`~pdsmc_ros.runs.builder.run_from_parameters`)."""
    values = {spec.name: value_of(node, spec.name) for spec in (*run_parameters(), *gain_parameters(applied=False))}
    return run_from_parameters(values, needs_gains=needs_gains)


def description_json(spec: RunSpec, mode: str) -> str:
    data = spec.describe()
    data["mode"] = mode
    return json.dumps(data, sort_keys=True)
