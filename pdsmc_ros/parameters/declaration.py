"""One node parameter declared as data, and the checks derived from it (ROS-free).

A :class:`ParameterSpec` holds what ros2_controllers' generate_parameter_library reads from a
controller's YAML (``joint_trajectory_controller_parameters.yaml``: ``type``, ``default_value``,
``description``, ``read_only``, ``validation`` such as ``bounds<>``, ``gt_eq<>``, ``one_of<>``,
and per-joint entries): its name, type, default, bounds or choices, description, whether it
holds one value per joint, and whether it is read-only. From it are derived:

- the rclpy declaration and its ``ParameterDescriptor`` (:mod:`.ros`): the type is static, so
  rclpy itself refuses a value of another type (``ros2 param set /controller kp 3000.0``: a
  double for a double array), as rclcpp refuses it for joint_trajectory_controller; a
  read-only parameter is refused by rclpy too;
- the start-up check (:meth:`ParameterSpec.coerce`): an override (``-p``, a params file) in the
  declared type, with the widenings a YAML file or a command line needs (an integer where a
  double is declared, a single number for a gain that stands for every joint), or one line
  naming the parameter and what it allows;
- the on-set check (:meth:`ParameterSpec.problem`): a value of the declared type within its
  bounds, or the reason -- never an exception, whatever arrives;
- the documentation's reference (:meth:`ParameterSpec.as_dict`, :func:`pdsmc_ros.parameters.catalog`).

The project goes beyond generate_parameter_library in one place: an integer given where a
double is declared is taken at start-up (``-p rate:=1000``, ``kp: [8000, 8000, 3000]`` in a
params file), since YAML and the command line write whole numbers without a decimal point.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from ..checks import is_real, is_whole
from ..errors import ConfigError

TYPES = ("bool", "int", "double", "string", "bool_array", "int_array", "double_array", "string_array")
"""The parameter types of ROS 2 this package declares (``rcl_interfaces/msg/ParameterType``'s names)."""

JOINT = "<joint>"
"""In the name of a parameter declared once per joint (:attr:`ParameterSpec.map_joints`)."""



def joint_name_matches(template: str, name: str) -> bool:
    """``name`` is ``template`` (``constraints.<joint>.goal``) for some joint."""
    if JOINT not in template:
        return name == template
    head, tail = template.split(JOINT, 1)
    middle = name[len(head):len(name) - len(tail)]
    return name.startswith(head) and name.endswith(tail) and len(name) > len(head) + len(tail) and "." not in middle


Choices = tuple[str, ...] | Callable[[], Sequence[str]]
"""Allowed strings, or a function giving them when asked (the registered robots and laws)."""


def _fmt(value: float) -> str:
    return str(value) if isinstance(value, int) else f"{value:g}"


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter of a node, declared once.

    Attributes
    ----------
    name : str
        The ROS parameter (``-p NAME:=``, a params file's key).
    type : str
        One of :data:`TYPES`.
    default : object
        Its value when not given; None: unset (e.g. a gain: the preset; ``torque_limit``: the
        arm's), or given by the node when it declares it (:func:`.ros.declare`'s ``defaults``).
    description : str
        What it is (the descriptor's description, the documentation).
    lo, hi : float or None
        Inclusive bounds of a number, or of every element of an array.
    lo_open : bool
        ``lo`` itself is refused (``> lo``).
    choices : tuple of str or callable
        The strings allowed (a string parameter); empty: any.
    special : tuple
        Values allowed besides the bounds (``busy_wait``'s -1: automatic).
    per_joint : bool
        An array with one value per joint (in ``joints`` order).
    map_joints : bool
        One parameter per joint: :data:`JOINT` in the name stands for each of the controller's
        ``joints`` (generate_parameter_library's ``__map_joints``: ``constraints.<joint>.goal``).
    one_for_all : bool
        A single value stands for every joint (a gain); a scalar given at start-up is taken so.
    read_only : bool
        Read once at start-up: rclpy refuses a set while the node runs. False only for the
        parameters the node applies at run time (the controller's gains).
    constraints : str or callable
        What it allows, in words, where the bounds and choices do not say it all (a function giving
        it when asked: the registered robots and laws).
    flag : str
        The ``pdsmc`` option that sets it (``--controller`` for ``type``), derived from this row
        (:func:`pdsmc_ros.cli.options.add_run_arguments`); empty: none.
    node : bool
        Declared by the nodes; False: a setting of the in-process run only (``payload_reading``).
    """

    name: str
    type: str
    default: Any
    description: str
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: Choices = ()
    special: tuple[Any, ...] = ()
    per_joint: bool = False
    map_joints: bool = False
    one_for_all: bool = False
    read_only: bool = True
    constraints: str | Callable[[], str] = ""
    flag: str = ""
    node: bool = True

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise ConfigError(f"parameter {self.name}: type {self.type!r} is not one of {', '.join(TYPES)}")

    def for_joints(self, joints: Sequence[str]) -> tuple[ParameterSpec, ...]:
        """The parameters it stands for (one per joint if :attr:`map_joints`, else itself)."""
        if not self.map_joints:
            return (self,)
        return tuple(replace(self, name=self.name.replace(JOINT, joint), map_joints=False,
                             description=self.description.replace(JOINT, joint)) for joint in joints)

    def matches(self, name: str) -> bool:
        """``name`` is this parameter (for a joint map: this parameter of some joint)."""
        return joint_name_matches(self.name, name) if self.map_joints else name == self.name

    # -- what it allows ----------------------------------------------------- #
    @property
    def is_array(self) -> bool:
        return self.type.endswith("_array")

    @property
    def element(self) -> str:
        """The type of one value (of each element of an array)."""
        return self.type.removesuffix("_array")

    def allowed_choices(self) -> tuple[str, ...]:
        return tuple(self.choices() if callable(self.choices) else self.choices)

    def bounds_text(self) -> str:
        """``in [1, 1000000]``, ``> 0``, ``>= 0``, or ``''``."""
        if self.lo is not None and self.hi is not None and not self.lo_open:
            return f"in [{_fmt(self.lo)}, {_fmt(self.hi)}]"
        low = "" if self.lo is None else f"{'>' if self.lo_open else '>='} {_fmt(self.lo)}"
        high = "" if self.hi is None else f"<= {_fmt(self.hi)}"
        return " and ".join(x for x in (low, high) if x)

    def allowed(self) -> str:
        """What it allows, as the end of ``parameter NAME must be ...``."""
        if self.constraints:
            return self.constraints() if callable(self.constraints) else self.constraints
        bounds = self.bounds_text()
        choices = self.allowed_choices()
        one = {
            "bool": "true or false",
            "int": "a whole number",
            "double": "a number",
            "string": "a string",
        }[self.element]
        if choices:
            one = "one of: " + ", ".join(choices)
        if bounds:
            one = f"{one} {bounds}"
        if not self.is_array:
            return one
        what = {"bool": "true/false values", "int": "whole numbers", "double": "numbers", "string": "strings"}
        shape = " (one per joint" + (", or one for every joint)" if self.one_for_all else ")") if self.per_joint else ""
        each = f", each {bounds}" if bounds else ""
        return f"a list of {what[self.element]}{shape}{each}"

    def _refusal(self, value: Any) -> str:
        return f"parameter {self.name} must be {self.allowed()}, got {value!r}"

    # -- start-up: an override in the declared type ---------------------------- #
    def coerce(self, value: Any) -> Any:
        """An override as the declared type (widening an integer to a double, a single number to a
        one-value list where it stands for every joint; an empty list of an unset array: unset).

        Raises
        ------
        ConfigError
            One line naming the parameter and what it allows, if the value is not of its type.
        """
        if value is None:
            return None
        if self.is_array:
            if self.one_for_all and self._scalar_ok(value):
                value = [value]
            if isinstance(value, str | bytes) or not isinstance(value, Sequence | bytearray):
                raise ConfigError(self._refusal(value))
            if len(value) == 0 and self.default is None:
                return None  # an empty list: not given (the preset, the arm's)
            if not all(self._scalar_ok(v) for v in value):
                raise ConfigError(self._refusal(value))
            return [self._scalar(v) for v in value]
        if self.element == "double" and isinstance(value, Sequence) and not isinstance(value, str) \
                and len(value) == 1 and self.one_for_all:
            value = value[0]  # a scalar gain written as a one-value list (pdsmc tune writes lists)
        if not self._scalar_ok(value):
            raise ConfigError(self._refusal(value))
        return self._scalar(value)

    def start_value(self, value: Any) -> Any:
        """The start-up check of an override: :meth:`coerce`, then :meth:`problem` (a ConfigError)."""
        value = self.coerce(value)
        reason = self.problem(value)
        if reason:
            raise ConfigError(reason)
        return value

    def _scalar_ok(self, value: Any) -> bool:
        element = self.element
        if element == "bool":
            return isinstance(value, bool)
        if element == "int":
            return is_whole(value)
        if element == "double":
            return is_real(value)
        return isinstance(value, str)

    def _scalar(self, value: Any) -> Any:
        element = self.element
        if element == "double":
            return float(value)
        if element == "int":
            return int(value)
        return value

    # -- any time: a value of the declared type within its bounds --------------- #
    def problem(self, value: Any, joints: int | None = None) -> str | None:
        """Why ``value`` is refused (one line naming the parameter), or None; never raises.

        ``joints``: the joint count a per-joint array must match (one value too, for a gain
        that stands for every joint); None: not checked here.
        """
        try:
            return self._problem(value, joints)
        except Exception as exc:  # noqa: BLE001 - a value nothing foresaw is a refusal, never an escape
            return f"parameter {self.name}: {value!r} refused ({type(exc).__name__}: {exc})"

    def _problem(self, value: Any, joints: int | None) -> str | None:
        if value is None:
            return None if self.default is None else self._refusal(value)
        values = value if self.is_array else [value]
        if self.is_array and (isinstance(value, str | bytes) or not isinstance(value, Sequence)):
            return self._refusal(value)
        if not all(self._scalar_ok(v) for v in values):
            return self._refusal(value)
        if self.per_joint and joints is not None and len(values) > 0:
            sizes = (joints, 1) if self.one_for_all else (joints,)
            if len(values) not in sizes:
                extra = " (or one for every joint)" if self.one_for_all else ""
                return f"parameter {self.name} needs {joints} values, one per joint{extra}, got {len(values)}"
        for v in values:
            if not self._value_ok(v):
                return self._refusal(value)
        return None

    def _value_ok(self, v: Any) -> bool:
        if v in self.special and not isinstance(v, bool):
            return True
        if self.element == "string":
            choices = self.allowed_choices()
            return not choices or v in choices
        if self.element in ("int", "double"):
            if not math.isfinite(v):
                return False
            if self.lo is not None and (v < self.lo or (self.lo_open and v == self.lo)):
                return False
            if self.hi is not None and v > self.hi:
                return False
        return True

    # -- the documentation's view ------------------------------------------------ #
    def as_dict(self) -> dict[str, Any]:
        """Plain data for the parameter reference (choices evaluated now: registered robots, laws)."""
        return {
            "name": self.name,
            "type": self.type,
            "default": self.default,
            "description": self.description,
            "allowed": self.allowed(),
            "lower": self.lo,
            "lower_open": self.lo_open,
            "upper": self.hi,
            "choices": list(self.allowed_choices()),
            "special": list(self.special),
            "per_joint": self.per_joint,
            "map_joints": self.map_joints,
            "one_for_all": self.one_for_all,
            "read_only": self.read_only,
        }


def check_values(specs: Sequence[ParameterSpec], values: Mapping[str, Any], *,
                 types_only: Collection[str] = ()) -> None:
    """The start-up check of ``values`` (a params file's, :func:`pdsmc_ros.parameters.params_file.node_parameters`):
    a ConfigError for the first its spec refuses; of ``types_only`` (the gains: the resolver's
    messages name the law) only the type is checked."""
    for spec in specs:
        for name in [n for n in values if spec.matches(n)]:
            concrete = replace(spec, name=name, map_joints=False)
            if spec.name in types_only:
                concrete.coerce(values[name])
            else:
                concrete.start_value(values[name])
