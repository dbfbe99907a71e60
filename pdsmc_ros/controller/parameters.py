"""The controller node's parameters: the run and the gains it is given, its own parameters,
its output limits and its gains changed at run time.

* :func:`declare_controller_run` -- the first step of a gain's way from ``-p kp:=`` (or a params
  file) to the torque: the run's parameters and every gain declared from the tables (the running
  law's gains read-write), the gains given handed with the run's settings to the run's resolution
  (:func:`~pdsmc_ros.runs.builder.run_from_parameters`, then
  :func:`~pdsmc_ros.runs.builder.resolve_gains`), whose :class:`~pdsmc_ros.runs.builder.RunSpec`
  the node hands to its core (:class:`~pdsmc_ros.controller.core.ControllerCore`), which builds
  the law from it (:class:`~pdsmc_ros.control.law.ControlLaw`; the formula:
  :mod:`pdsmc_ros.control.laws`).
* :func:`declare_controller_parameters` -- ``joints`` (by name, any order: the order of the
  command's ``data``, of gains and torque limits given as parameters and of every per-joint
  output), ``autostart``, ``torque_limit``, ``enforce_limits``, ``stale_periods``, the action's
  default tolerances (``constraints.goal_time``, ``constraints.stopped_velocity_tolerance``,
  ``constraints.<joint>.trajectory`` and ``.goal``) and how trajectories are taken
  (``cmd_timeout``, ``allow_partial_joints_goal``, ``allow_nonzero_velocity_at_trajectory_end``,
  ``allowed_start_tolerance``, ``reject_beyond_limits``), as joint_trajectory_controller names
  them: declared once in :data:`~pdsmc_ros.parameters.CONTROLLER` (read-only: a running
  controller does not re-read them).
* :func:`declare_limit_parameters` -- the output limits: ``soft_limits.k_position`` and
  ``soft_limits.k_velocity`` are ros2_control's soft-limit gains
  (:func:`pdsmc_ros.control.soft_limits.soft_limit`); ``runaway.velocity_factor``,
  ``runaway.position_margin`` and ``runaway.stop`` set the runaway guard
  (:class:`pdsmc_ros.controller.commanding.RunawayGuard`). All are read at start (read-only),
  and none applies with ``enforce_limits:=false``.
* :class:`GainUpdates` -- gains changed at run time (``ros2 param set``): the on-set callback
  resolves a change by the same resolver and validates it (the run it gives must pass the
  stability check), the post-set callback hands it to the core (the same law, its new gains).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..control import GAINS, Gains
from ..control.soft_limits import effort_only_table, robot_soft_limits
from ..errors import ConfigError, InvalidInputError, PdsmcError
from ..parameters import BUSY_WAIT, CONTROLLER, OUTPUT_LIMITS
from ..parameters.joint_map import JointMap
from ..parameters.ros import declare, declare_run_parameters, value_of
from ..robots import make_robot
from ..robots.base import FloatArray, Manipulator
from ..robots.catalog import resolve_robot
from ..ros.node_run import take_robot_description
from ..runs.builder import RunSpec, resolve_gains, run_from_parameters
from .commanding import RunawayGuard
from .goals import GoalSettings, Tolerances
from .joint_trajectory import TrajectoryRules
from .sidecar.gain_check import checked


@dataclass(frozen=True)
class ControllerRun:
    """What the controller node starts from: the run its parameters name (``spec``, its gains
    resolved, in robot order), the mode, the busy-wait, ``stability`` (the keywords of
    :func:`~pdsmc_ros.control.stability.check_rate` its gains must pass), ``joint_map`` (its
    ``joints``) and ``values`` (every parameter declared so far, by name; None: not set)."""

    spec: RunSpec
    mode: str
    busy_wait: float
    stability: dict[str, Any]
    joint_map: JointMap
    values: dict[str, Any]


def declare_controller_run(node: Node) -> ControllerRun:
    """Declare the controller's run: the run's parameters, every gain (the law's read-write, checked
    on set by :class:`GainUpdates`; one params file serves every node and law), the stability
    check's, ``busy_wait`` and the controller's own (:data:`~pdsmc_ros.parameters.CONTROLLER`), and
    build the run they name.

    The gains given (``-p kp:=``, a params file) are in ``joints`` order; the run's resolution
    (:func:`~pdsmc_ros.runs.builder.run_from_parameters`) puts them in robot order over the presets
    and scales them by the scenario. No preset and none given is an error.

    Raises
    ------
    ConfigError
        One line naming the parameter and what is allowed.
    """
    values = declare_run_parameters(node, gains=True)  # the run's table, every gain, the stability check's
    values.update(declare(node, (BUSY_WAIT,)))  # used in real time
    take_robot_description(node, values["robot"])
    try:
        robot_joints = make_robot(resolve_robot(values["robot"])).joint_names
    except ConfigError as exc:
        raise ConfigError(f"parameters: {exc}") from None
    values.update(declare(node, CONTROLLER, defaults={"joints": list(robot_joints)}))
    joint_map = JointMap(robot_joints, values["joints"])
    spec = run_from_parameters(values, joint_order=joint_map.user_of)  # the gains given, resolved
    mode = values["mode"]
    return ControllerRun(spec, mode, float(values["busy_wait"]), stability_from_values(values, mode), joint_map,
                         values)


def stability_from_values(values: dict[str, Any], mode: str) -> dict[str, Any]:
    """``check_rate``'s keywords from ``stability_margin`` and ``delay_periods`` (checked when declared)."""
    return {"mode": mode, "delay_periods": int(values["delay_periods"]),
            "margin": float(values["stability_margin"]) or None, "entry": "node"}


@dataclass(frozen=True)
class ControllerParameters:
    """The controller's own parameters, validated; vectors in ``joints`` order."""

    joint_map: JointMap
    autostart: bool
    torque_limit: np.ndarray | None  # the clamp (joints order): torque_limit, else the arm's; None: opt-out
    enforce_limits: bool
    stale_periods: int
    goal_settings: GoalSettings  # trajectories and goals: JTC's parameters, the default tolerances (robot order)
    action_introspection: str  # accepted goals as SendGoal service events: disabled, metadata or contents
    goal_process: str  # real time: the action and the parameters in a process of their own: auto, on or off

    @property
    def joints(self) -> tuple[str, ...]:
        return self.joint_map.joints


def declare_controller_parameters(node: Node, robot: Manipulator) -> ControllerParameters:
    """Declare the controller's parameters (if :func:`declare_controller_run` has
    not) and return them validated; a ConfigError naming the parameter if bad (an unknown joint name
    lists the robot's)."""
    values = declare(node, CONTROLLER, defaults={"joints": list(robot.joint_names)})
    joint_map = JointMap(robot.joint_names, values["joints"])
    limit = values["torque_limit"]
    if limit is not None and len(limit) != robot.n:
        raise ConfigError(f"parameter torque_limit needs {robot.n} values > 0 (N m), one per joint, got {limit}")
    limit = None if limit is None else np.asarray(limit, dtype=float)
    if not values["enforce_limits"]:
        if limit is not None:
            node.get_logger().warn("enforce_limits is false: torque_limit is not applied")
        limit = None
    elif limit is None:
        effort = getattr(robot, "effort_limits", None)
        limit = None if effort is None else joint_map.to_user(np.asarray(effort, dtype=float))
    per_joint = {kind: joint_map.to_robot([values[f"constraints.{joint}.{kind}"] for joint in joint_map.joints])
                 for kind in ("trajectory", "goal")}
    defaults = Tolerances.defaults(robot.n, stopped_velocity=values["constraints.stopped_velocity_tolerance"],
                                   goal_time=values["constraints.goal_time"], trajectory=per_joint["trajectory"],
                                   goal=per_joint["goal"])
    rules = TrajectoryRules(values["allow_partial_joints_goal"], values["allow_nonzero_velocity_at_trajectory_end"])
    stop = None
    if values["constraints.decelerate_on_cancel"]:
        decelerations = [values[f"constraints.{joint}.max_deceleration_on_cancel"] for joint in joint_map.joints]
        unset = [joint for joint, a in zip(joint_map.joints, decelerations, strict=True) if not a > 0.0]
        if not unset:
            stop = np.asarray(joint_map.to_robot(decelerations), dtype=float)
        else:  # as JTC: a joint without a deceleration turns the feature off, with a warning
            node.get_logger().warn(f"constraints.decelerate_on_cancel is true but constraints.<joint>."
                                   f"max_deceleration_on_cancel is not > 0 for {', '.join(unset)}: holding at once")
    try:
        settings = GoalSettings(rules, defaults, values["cmd_timeout"], values["allowed_start_tolerance"],
                                values["reject_beyond_limits"], stop_deceleration=stop)
    except ValueError as exc:
        raise ConfigError(f"parameter {exc}") from None
    return ControllerParameters(joint_map, values["autostart"], limit, values["enforce_limits"],
                                values["stale_periods"], settings, values["action_introspection"],
                                values["goal_process"])


def declare_limit_parameters(node: Node, robot: Manipulator, params: ControllerParameters, period: float,
                             lockstep: bool, start_q: FloatArray) -> tuple[FloatArray | None, RunawayGuard | None]:
    """Declare the output-limit parameters; the output-limit table (robot order) and the runaway
    guard, each None with ``enforce_limits:=false``.

    Real time: the soft limits about the run's start configuration ``start_q``
    (:func:`~pdsmc_ros.control.soft_limits.robot_soft_limits`) and the runaway guard. Lockstep: the
    effort clamp alone, as the in-process simulator runs (a lockstep run is a simulation whose
    divergence test must see an unstable law run away: soft limits would hold it at the velocity
    limit), and no runaway guard.

    Raises
    ------
    ConfigError
        A value out of range or of the wrong type, naming the parameter.
    """
    values = declare(node, OUTPUT_LIMITS)  # read-only; each of its type and in its bounds
    k_position, k_velocity = values["soft_limits.k_position"], values["soft_limits.k_velocity"]
    factor, margin, stop = values["runaway.velocity_factor"], values["runaway.position_margin"], values["runaway.stop"]
    if k_velocity is not None and len(k_velocity) != robot.n:
        raise ConfigError(f"parameter soft_limits.k_velocity must be {robot.n} numbers >= 0 (N m s/rad, joints order) "
                          f"or empty, got {k_velocity!r}")
    if not params.enforce_limits:
        return None, None
    joint_map = params.joint_map
    effort = (np.asarray(robot.effort_limits, dtype=float) if params.torque_limit is None
              else joint_map.to_robot(params.torque_limit))
    if lockstep:
        return effort_only_table(effort, robot.n), None
    gains = None if not k_velocity else joint_map.to_robot([float(v) for v in k_velocity])
    try:
        table = robot_soft_limits(robot, start_q, 1.0 / period, k_position=float(k_position),
                                  k_velocity=gains, effort=effort)
    except InvalidInputError as exc:
        raise ConfigError(f"parameter {exc}") from None
    runaway = RunawayGuard(robot.joint_names, robot.position_limits, robot.velocity_limits, effort,
                           inertia=lambda q: np.diag(robot.mass_matrix(q)), period=period,
                           velocity_factor=float(factor), position_margin=float(margin),
                           stop=str(stop))
    return table, runaway


class GainUpdates:
    """Run-time gain changes, ros2/demos style: the on-set callback validates, the
    post-set callback applies.

    A change is resolved as at start-up, by the one resolver
    (:func:`~pdsmc_ros.runs.builder.resolve_gains`: the presets, the gains given as parameters with
    the change, in ``joints`` order, then the scenario's factors), and passes exactly the checks
    of start-up (:meth:`Gains.from_mapping`'s and the zero-order-hold stability check at the
    running rate, ``check``) or is refused with the reason (``ros2 param set`` shows it: for an
    unstable gain, the lowest stable rate). Whatever the check raises (a ``LinAlgError`` of gains
    of 1e308) is a refusal, never an exception in the executor. ``apply`` receives the accepted
    gains only after the parameters are set, from the post-set callback.
    """

    def __init__(self, node: Node, spec: RunSpec, check: Callable[[RunSpec], object],
                 apply: Callable[[Gains], None], *, joint_map: JointMap | None = None) -> None:
        self.spec = spec
        self.check = check
        self.apply = apply
        self.joint_order = None if joint_map is None else joint_map.user_of
        # the gains given as parameters at start (-p, params files), in joints order
        self.given: dict[str, Any] = {name: value_of(node, name) for name in GAINS if value_of(node, name) is not None}
        self.pending: tuple[Gains, dict[str, Any]] | None = None
        node.add_on_set_parameters_callback(self.validate)
        node.add_post_set_parameters_callback(self.applied)

    def validate(self, params: Sequence[Parameter]) -> SetParametersResult:
        self.pending = None
        changes = {p.name: p.value for p in params if p.name in GAINS}
        if not changes:
            return SetParametersResult(successful=True)
        given = {**self.given, **changes}
        spec = self.spec
        try:
            gains = resolve_gains(spec.robot, spec.contour, spec.controller, scenario=spec.scenario,
                                  layers=[given], joint_order=self.joint_order)
            checked(self.check, dataclasses.replace(spec, gains=gains))
        except Exception as exc:  # noqa: BLE001 - a refusal with the reason, never an escape into the executor
            reason = str(exc) if isinstance(exc, PdsmcError) else f"{', '.join(changes)}: {type(exc).__name__}: {exc}"
            return SetParametersResult(successful=False, reason=" ".join(reason.split()))
        self.pending = (gains, given)
        return SetParametersResult(successful=True)

    def applied(self, params: Sequence[Parameter]) -> None:
        if self.pending is None or not any(p.name in GAINS for p in params):
            return
        (gains, given), self.pending = self.pending, None
        self.take(gains, given)

    def take(self, gains: Gains, given: dict[str, Any]) -> None:
        """Apply ``gains``, resolved from the gain parameters ``given`` and accepted: here (the
        post-set callback) or by the goal process, which serves the controller's parameters in real time."""
        self.given = dict(given)
        self.spec = dataclasses.replace(self.spec, gains=gains)
        self.apply(gains)
