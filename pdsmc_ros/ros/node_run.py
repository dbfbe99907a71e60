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
from ..parameters import BUSY_WAIT, CONTROLLER, STABILITY, gain_parameters, run_parameters
from ..parameters.joint_map import JointMap
from ..parameters.ros import declare, guard, value_of
from ..robots import make_robot
from ..robots.catalog import ROBOT_DESCRIPTION, register_description, resolve_robot
from ..runs.builder import RunSpec, run_from_settings
from .robot_description import receive_robot_description


@dataclass(frozen=True)
class NodeRun:
    """What every node starts from: the run its parameters name, the mode and the busy-wait;
    for the controller, ``stability`` (the keywords of :func:`~pdsmc_ros.control.stability.check_rate`
    its gains must pass) and ``joint_map`` (its ``joints``); ``values``: every parameter declared
    so far, by name (None: not set)."""

    spec: RunSpec
    mode: str
    busy_wait: float
    stability: dict[str, Any] = dataclasses.field(default_factory=dict)
    joint_map: JointMap | None = None
    values: dict[str, Any] = dataclasses.field(default_factory=dict)


def declare_node_run(node: Node, *, gains: bool = False) -> NodeRun:
    """The start-up lines of every node: declare the run's parameters, the gains and ``busy_wait``
    and build the RunSpec they name (a ConfigError if bad). ``gains``: the node is the controller
    (it needs them: no preset and none given is an error; they can change at run time; it also
    declares its stability and own parameters, :data:`~pdsmc_ros.parameters.STABILITY` and
    :data:`~pdsmc_ros.parameters.CONTROLLER`, and its gains given as parameters follow its
    ``joints``); the other nodes take them read-only and run without. Every parameter of the
    tables is read-only but the controller's gains (:func:`~pdsmc_ros.parameters.ros.guard`).

    The gains (``-p kp:=``, a params file) go through :func:`spec_from_values` to the one resolver
    (:func:`~pdsmc_ros.runs.builder.resolve_gains`) into ``spec``; the controller node hands ``spec`` to
    its core (:class:`~pdsmc_ros.controller.core.ControllerCore`), which runs the law with them."""
    values = declare_run_parameters(node, gains=gains)
    values.update(declare(node, (BUSY_WAIT,)))  # used in real time
    if values["robot"] == ROBOT_DESCRIPTION:
        try:
            register_description(receive_robot_description(node))
        except ConfigError as exc:
            raise ConfigError(f"parameter robot: {exc}") from None
    joint_map = None
    if gains:
        try:
            robot_joints = make_robot(resolve_robot(values["robot"])).joint_names
        except ConfigError as exc:
            raise ConfigError(f"parameters: {exc}") from None
        values.update(declare(node, CONTROLLER, defaults={"joints": list(robot_joints)}))
        joint_map = JointMap(robot_joints, values["joints"])
    spec = spec_from_values(values, needs_gains=gains, joint_order=None if joint_map is None else joint_map.user_of)
    mode = values["mode"]
    stability = stability_from_values(values, mode) if gains else {}
    return NodeRun(spec, mode, float(values["busy_wait"]), stability, joint_map, values)


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
    """The RunSpec named by the node's declared parameters (:func:`spec_from_values`)."""
    values = {spec.name: value_of(node, spec.name) for spec in (*run_parameters(), *gain_parameters(applied=False))}
    return spec_from_values(values, needs_gains=needs_gains)


def spec_from_values(values: dict[str, Any], *, needs_gains: bool = True,
                     joint_order: Any = None) -> RunSpec:
    """Build and validate the RunSpec the parameter ``values`` name.

    The gains given (``-p kp:=``, a params file: rcl merges both) are the overrides layer of
    :func:`~pdsmc_ros.runs.builder.make_run`, the one builder ``pdsmc simulate`` uses too, in
    ``joint_order`` (the controller's ``joints``): its resolver puts them in robot order, replaces
    the preset's with them and scales them by the scenario's factors, as in-process. An arm
    without preset gains needs them all given when ``needs_gains`` (the controller); the other
    nodes run with neutral placeholders.

    Raises
    ------
    ConfigError
        With a message naming the parameter and what is allowed.
    """
    overrides = {g.name: values[g.name] for g in gain_parameters(applied=False) if values.get(g.name) is not None}
    settings = {spec.name: values[spec.name] for spec in run_parameters()}
    try:
        return run_from_settings(settings, overrides=overrides, needs_gains=needs_gains, joint_order=joint_order)
    except ConfigError as exc:
        raise ConfigError(f"parameters: {exc}") from None


def stability_from_values(values: dict[str, Any], mode: str) -> dict[str, Any]:
    """``check_rate``'s keywords from ``stability_margin`` and ``delay_periods`` (checked when declared)."""
    return {"mode": mode, "delay_periods": int(values["delay_periods"]),
            "margin": float(values["stability_margin"]) or None, "entry": "node"}


def description_json(spec: RunSpec, mode: str) -> str:
    data = spec.describe()
    data["mode"] = mode
    return json.dumps(data, sort_keys=True)
