"""Robots by name: the registry and their parameters from ``config/robots.yaml``.

The registry holds, per name, what builds the robot (a :class:`RobotFactory`): a
:class:`~pdsmc_ros.robots.base.Manipulator` subclass, or a URDF arm's
:class:`~.urdf_robot.UrdfArm` (its model and settings, an instance). The built-in robots
and a robot of an installed package are entry points of the group ``pdsmc_ros.robots``
(:mod:`pdsmc_ros.plugins`), naming a factory or a :class:`RobotEntry` (a factory with its
configuration); a robot is also registered in-process with :func:`register_robot`.
:func:`make_robot` builds the robot from its name; what differs between kinds of robot is a
method or attribute of the robot. A robot's parameters and run settings live under its name in
``config/robots.yaml`` or, for a robot defined outside the package, in its own configuration
(:attr:`RobotEntry.config`, the mapping given to :func:`register_robot`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar, cast

from ..config import choice, load_config
from ..errors import ConfigError, InvalidInputError
from ..plugins import ROBOT_GROUP, PluginGroup, Registered
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

_ROBOTS: dict[str, RobotFactory] = {}
_CONFIGS: dict[str, Mapping[str, Any]] = {}  # robots registered with their own configuration


@dataclass(frozen=True)
class RobotEntry:
    """A robot declaring itself, as an entry point of ``pdsmc_ros.robots`` names it.

    Attributes
    ----------
    factory : RobotFactory
        A :class:`Manipulator` subclass or a URDF arm, named as the entry point.
    config : mapping or None
        Its parameters and settings in the shape of one entry of ``config/robots.yaml``
        (links, motors, ``control_rate``, ``sample_rate``, ``contour_bound``); None: its entry
        of that file (a built-in robot).
    """

    factory: RobotFactory
    config: Mapping[str, Any] | None = None


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
    """Register a robot under its ``name`` in-process (a class decorator, or a call with a URDF
    arm); a robot of an installed package is an entry point instead (:mod:`pdsmc_ros.plugins`).

    Parameters
    ----------
    robot : RobotFactory
        A :class:`Manipulator` subclass, or a URDF arm (:class:`~.urdf_robot.UrdfArm`), with a
        unique, non-empty ``name``.
    config : mapping, optional
        Its parameters and settings, in the shape of one entry of
        ``config/robots.yaml``; by default that entry is read from the file.
    """
    PLUGINS.load_builtins()

    def register(factory: Factory) -> Factory:
        _register(factory, config)
        return factory

    return register if robot is None else register(robot)


def _register(factory: RobotFactory, config: Mapping[str, Any] | None) -> None:
    name = getattr(factory, "name", None)
    if not name or not isinstance(name, str) or not callable(getattr(factory, "create", None)):
        raise InvalidInputError(f"robot {factory!r} has no name or no create method (a RobotFactory)")
    if name in _ROBOTS and _ROBOTS[name] is not factory:
        raise InvalidInputError(f"a robot named {name!r} is already registered ({_ROBOTS[name]!r})")
    _ROBOTS[name] = factory
    if config is not None:
        _CONFIGS[name] = dict(config)


def _register_entry_point(name: str, loaded: object) -> None:
    """What :data:`PLUGINS` registers: the factory or :class:`RobotEntry` an entry point names."""
    # a factory is checked by what it has (a name, a create method) when registered
    entry = loaded if isinstance(loaded, RobotEntry) else RobotEntry(cast(RobotFactory, loaded))
    if getattr(entry.factory, "name", None) != name:
        raise ValueError(f"names the robot {getattr(entry.factory, 'name', None)!r}: an entry point is named as "
                         "its robot")
    _register(entry.factory, entry.config)


PLUGINS = PluginGroup(ROBOT_GROUP, _register_entry_point)
"""The entry points of ``pdsmc_ros.robots``: the built-in robots, then installed packages' robots."""

ROBOTS: Mapping[str, RobotFactory] = Registered(_ROBOTS, PLUGINS.load_all)
"""What builds each registered robot, by name: the built-in ones in their order (the thesis's,
serial first), then those registered in-process and installed packages' (read-only)."""


def unregister_robot(name: str) -> None:
    """Remove a registered robot (a test's own robot, for example)."""
    _ROBOTS.pop(name, None)
    _CONFIGS.pop(name, None)


def robot_names() -> tuple[str, ...]:
    """Names of the registered robots, installed packages' included."""
    return tuple(ROBOTS)


def find_robot(name: str) -> RobotFactory | None:
    """What builds the registered robot ``name`` (an installed package's loaded on first use), or None.

    Raises
    ------
    ConfigError
        The installed plugin of that name does not load (one line naming its distribution and
        entry point).
    """
    PLUGINS.load_builtins()
    if name not in _ROBOTS:
        PLUGINS.load(name)
    return _ROBOTS.get(name)


def _factory(name: str) -> RobotFactory:
    found = find_robot(name) if isinstance(name, str) else None
    return found if found is not None else _ROBOTS[choice(name, robot_names(), "robot")]


def robot_config(name: str) -> Mapping[str, Any]:
    """The robot's configuration entry (its own, else ``config/robots.yaml``)."""
    _factory(name)
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
    """Build a registered robot by name; a robot built from :class:`RobotParams` takes its
    configured ones unless ``params`` are given."""
    factory = _factory(name)
    if params is None and isinstance(factory, type) and issubclass(factory, Manipulator):
        params = robot_params(name)
    return factory.create(payload, params=params)
