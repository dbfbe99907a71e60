"""The rclpy side of the parameter tables: declarations with descriptors, and the on-set guard.

:func:`declare` declares a table on a node, statically typed (as generate_parameter_library
declares joint_trajectory_controller's): every override is first brought to the declared type
and checked (:meth:`ParameterSpec.coerce <.declaration.ParameterSpec.coerce>`, one line naming
the parameter if it cannot be), so a node never starts on a value its table refuses and never
dies in rclpy's own type check. :func:`guard` is the on-set callback: rclpy refuses a read-only
parameter and a value of another type before it runs; it refuses what the table refuses and
what the node's own check refuses, and it returns a refusal, never raises, whatever arrives.
:func:`declare_run_parameters` declares and guards the table every node of a run shares: the run's
settings and every gain (:func:`guard_run_parameters` guards it alone, on the goal process's stand-in).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..control.registry import law
from ..errors import ConfigError
from ..rclpy_internals import declared_value, parameter_overrides
from .declaration import ParameterSpec
from .run_table import run_parameters
from .tables import STABILITY, gain_parameters

ROS_TYPES = {
    "bool": Parameter.Type.BOOL,
    "int": Parameter.Type.INTEGER,
    "double": Parameter.Type.DOUBLE,
    "string": Parameter.Type.STRING,
    "bool_array": Parameter.Type.BOOL_ARRAY,
    "int_array": Parameter.Type.INTEGER_ARRAY,
    "double_array": Parameter.Type.DOUBLE_ARRAY,
    "string_array": Parameter.Type.STRING_ARRAY,
}

READ_AT_START = ("use_sim_time",)
"""Parameters rclpy declares on every node that these nodes read once: ``use_sim_time`` set at run
time would switch a running loop's clock (a lockstep trajectory's time froze)."""


def descriptor(spec: ParameterSpec, *, ranged: bool = True) -> ParameterDescriptor:
    """The rclpy descriptor of ``spec``: its type, description, what it allows, its range (a
    scalar's, widened to its special values, e.g. busy_wait's -1; none unless ``ranged``: a value
    the node checks itself, whose message says more) and read-only flag."""
    desc = ParameterDescriptor(description=spec.description, additional_constraints=spec.allowed(),
                               read_only=spec.read_only, type=ROS_TYPES[spec.type].value)
    if ranged and spec.type in ("double", "int") and spec.lo is not None and spec.hi is not None:
        lo = min([spec.lo, *spec.special])
        hi = max([spec.hi, *spec.special])
        if spec.type == "double":
            desc.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi), step=0.0)]
        else:
            desc.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=0)]
    return desc


def declare(node: Node, specs: Sequence[ParameterSpec], *, defaults: Mapping[str, Any] | None = None,
            checked: bool = True) -> dict[str, Any]:
    """Declare ``specs`` on ``node`` and return their values (None: not set).

    Each override (``-p``, a params file) is brought to the declared type first; ``defaults``
    replace the table's defaults (those a node knows only when it starts: the robot's joints,
    the mode's real-time settings). ``checked``: each value is also checked against its bounds
    (False: a later check gives the message, e.g. the gains', by :class:`~pdsmc_ros.control.Gains`).
    A parameter the node already declared keeps its value.

    Raises
    ------
    ConfigError
        One line naming the parameter and what it allows.
    """
    overrides = parameter_overrides(node)
    values: dict[str, Any] = {}
    for spec in _expanded(specs, values, defaults):
        if node.has_parameter(spec.name):
            values[spec.name] = value_of(node, spec.name)
            continue
        default = (defaults or {}).get(spec.name, spec.default)
        given = overrides.get(spec.name)
        check = spec.start_value if checked else spec.coerce
        value = default if given is None else check(given.value)
        kind = ROS_TYPES[spec.type]
        if given is not None:
            if value is None:
                del overrides[spec.name]  # an empty list: not given
            else:
                overrides[spec.name] = Parameter(spec.name, kind, value)
        try:
            node.declare_parameter(spec.name, kind if value is None else Parameter(spec.name, kind, value).value,
                                   descriptor(spec, ranged=checked))
        except (ParameterException, TypeError, ValueError) as exc:  # not expected: the value was checked above
            raise ConfigError(f"parameter {spec.name}: {' '.join(str(exc).split())}") from None
        values[spec.name] = value
    return values


def _expanded(specs: Sequence[ParameterSpec], values: dict[str, Any],
              defaults: Mapping[str, Any] | None) -> Iterator[ParameterSpec]:
    """``specs`` with those declared once per joint expanded for the ``joints`` declared before them."""
    for spec in specs:
        if spec.map_joints:
            joints = values.get("joints") or (defaults or {}).get("joints") or ()
            yield from spec.for_joints([str(j) for j in joints])
        else:
            yield spec


def value_of(node: Node, name: str) -> Any:
    """A declared parameter's value, None if unset (rclpy's ``get_parameter`` raises for an
    unset statically typed parameter: a gain not given)."""
    return declared_value(node, name)


Check = Callable[[Sequence[Parameter]], "str | None"]
"""A node's own check of parameters about to be set (those its table lets through): the refusal's
reason, or None to accept."""


OnSet = Callable[[list[Parameter]], SetParametersResult]


def guard(node: Node, specs: Sequence[ParameterSpec], *, check: Check | None = None,
          checked_by_node: Collection[str] = (), joints: int | None = None) -> OnSet:
    """Add the on-set callback of ``specs`` to ``node`` and return it.

    A set of a parameter of the table is refused, with a one-line reason, if it is read-only
    (rclpy refuses it first), of another type (rclpy too), or outside what the table allows
    (``joints``: the length of a per-joint array); names in ``checked_by_node`` are left to
    ``check`` (the controller's gains: its resolver and the stability check say why); ``use_sim_time``
    is refused (:data:`READ_AT_START`). Whatever goes wrong inside is a refusal naming the
    exception, never an exception in the executor (issue 37: one escaped and the node's parameter
    and lifecycle services stopped answering). Declarations pass (the declaring code checks them).
    """
    table = {spec.name: spec for spec in specs if not spec.map_joints}
    per_joint = [spec for spec in specs if spec.map_joints]

    def on_set(params: list[Parameter]) -> SetParametersResult:
        try:
            if not all(node.has_parameter(p.name) for p in params):
                return SetParametersResult(successful=True)  # a declaration: checked by declare()
            for param in params:
                spec = table.get(param.name) or next((s for s in per_joint if s.matches(param.name)), None)
                if param.name in READ_AT_START:
                    return _refused(f"{param.name} is read at start-up and cannot change while the node runs")
                if spec is None:
                    continue
                if spec.read_only:
                    return _refused(f"{param.name} is read at start-up and cannot change while the node runs")
                if param.name not in checked_by_node:
                    reason = spec.problem(param.value, joints)
                    if reason:
                        return _refused(reason)
            reason = check(params) if check is not None else None
            return _refused(reason) if reason else SetParametersResult(successful=True)
        except Exception as exc:  # noqa: BLE001 - a refusal, never an escape into the executor
            names = ", ".join(p.name for p in params)
            return _refused(f"{names}: refused ({type(exc).__name__}: {exc})")

    node.add_on_set_parameters_callback(on_set)
    return on_set


def _refused(reason: str) -> SetParametersResult:
    return SetParametersResult(successful=False, reason=" ".join(str(reason).split()))


def declare_run_parameters(node: Node, *, gains: bool = False) -> dict[str, Any]:
    """Declare the run's parameters and the gains (every node: one params file or ``-p kp:=``
    serves all; only the controller uses them, ``gains``, and it also declares
    :data:`~pdsmc_ros.parameters.STABILITY`), guard them (:func:`guard`:
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
    the stability parameters on ``node`` (:func:`guard`); the gains are
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
