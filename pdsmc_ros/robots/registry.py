"""Robots by name: the registry and their parameters from ``config/robots.yaml``.

The registry holds, per name, what builds the robot (a :class:`RobotFactory`): a
:class:`~pdsmc_ros.robots.base.Manipulator` subclass decorated with
:func:`register_robot`, or a URDF arm's :class:`~.urdf_arm.UrdfArm` (its model and
settings, an instance). :func:`make_robot` builds the robot from its name; what differs
between kinds of robot is a method or attribute of the robot. A robot's parameters and
run settings live under its name in ``config/robots.yaml`` (or, for a robot defined
outside the package, in the mapping given to :func:`register_robot`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

from ..config import choice, load_config
from ..errors import ConfigError, InvalidInputError
from .base import Manipulator, RobotParams


class RobotFactory(Protocol):
    """What the registry holds for a robot: its name and how to build it."""

    @property
    def name(self) -> str:
        """The name it is registered under."""
        ...

    def create(self, payload: float = 0.0, *, params: RobotParams | None = None) -> Manipulator:
        """The robot carrying ``payload`` kg, with ``params`` (by default its configured ones)."""
        ...


Factory = TypeVar("Factory", bound=RobotFactory)

ROBOTS: dict[str, RobotFactory] = {}
"""What builds each registered robot, by name, in registration order."""

_CONFIGS: dict[str, Mapping[str, Any]] = {}  # robots registered with their own configuration


@dataclass(frozen=True)
class RobotSettings:
    """How runs of a robot are set up (``config/robots.yaml``).

    Attributes
    ----------
    control_rate : float
        Default control rate (Hz); the thesis robots' rates reproduce its
        continuous-time results (docs/THESIS_NOTES.md section 1).
    sample_rate : float
        Rate (Hz) at which errors are sampled for the statistics (Section 4.2).
    contour_bound : float
        Contour error bound (m) of the "% within bound" statistic.
    """

    control_rate: float
    sample_rate: float
    contour_bound: float


def register_robot(
    robot: Factory | None = None, *, config: Mapping[str, Any] | None = None
) -> Factory | Callable[[Factory], Factory]:
    """Register a robot under its ``name`` (a class decorator, or a call with a URDF arm).

    Parameters
    ----------
    robot : RobotFactory
        A :class:`Manipulator` subclass, or a URDF arm (:class:`~.urdf_arm.UrdfArm`), with a
        unique, non-empty ``name``.
    config : mapping, optional
        Its parameters and settings, in the shape of one entry of
        ``config/robots.yaml``; by default that entry is read from the file.
    """

    def register(factory: Factory) -> Factory:
        name = factory.name
        if not name or not isinstance(name, str):
            raise InvalidInputError(f"robot {factory!r} has no name")
        if name in ROBOTS and ROBOTS[name] is not factory:
            raise InvalidInputError(f"a robot named {name!r} is already registered ({ROBOTS[name]!r})")
        ROBOTS[name] = factory
        if config is not None:
            _CONFIGS[name] = dict(config)
        return factory

    return register if robot is None else register(robot)


def unregister_robot(name: str) -> None:
    """Remove a registered robot (a test's own robot, for example)."""
    ROBOTS.pop(name, None)
    _CONFIGS.pop(name, None)


def robot_names() -> tuple[str, ...]:
    """Names of the registered robots."""
    return tuple(ROBOTS)


def robot_config(name: str) -> Mapping[str, Any]:
    """The robot's configuration entry (its own, else ``config/robots.yaml``)."""
    choice(name, robot_names(), "robot")
    if name in _CONFIGS:
        return _CONFIGS[name]
    data = load_config("robots")
    if name not in data:
        raise ConfigError(f"robot {name!r} has no entry in config/robots.yaml")
    return data[name]


def robot_params(name: str) -> RobotParams:
    """Structural and motor parameters of the named robot."""
    return RobotParams.from_mapping(robot_config(name), name=f"robots.yaml:{name}")


def robot_settings(name: str) -> RobotSettings:
    """Run settings of the named robot."""
    data = robot_config(name)
    try:
        return RobotSettings(control_rate=float(data["control_rate"]), sample_rate=float(data["sample_rate"]),
                             contour_bound=float(data["contour_bound"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f"robots.yaml:{name}: malformed run settings ({exc!r})") from exc


def make_robot(name: str, *, payload: float = 0.0, params: RobotParams | None = None) -> Manipulator:
    """Build a registered robot by name."""
    return ROBOTS[choice(name, robot_names(), "robot")].create(payload, params=params)
