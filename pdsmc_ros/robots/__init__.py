"""Robots: one module per robot (numpy model and compiled form side by side) and a registry.

Adding a robot: a :class:`Manipulator` subclass, an entry point of the group
``pdsmc_ros.robots`` naming it (a built-in one: :data:`pdsmc_ros.plugins.BUILTIN_ENTRY_POINTS`;
a robot of one's own package: its packaging, naming a :class:`RobotEntry` with its configuration)
or registered in-process with :func:`register_robot` (a test registers its own), and its entry in
``config/robots.yaml`` (or its own configuration). A robot without a compiled form runs behind
:mod:`.python_form`'s; one with its own adds one entry to :data:`.compiled.COMPILED`. A URDF arm
is no class: an instance of :class:`UrdfArm` (``robot:=`` a name of ``config/urdf_arms.yaml`` or
a ``.urdf`` path).
"""

# before any kernel runs: drop cached kernels built from other sources (see kernel_cache)
from ..kernels.cache import refresh as _refresh_kernel_cache  # noqa: I001

_refresh_kernel_cache()

from .serial_3r import Serial3R  # noqa: E402, I001
from .parallel_5r import FiveBarState, Parallel5R  # noqa: E402
from .base import GRAVITY, FloatArray, LinkParams, Manipulator, RobotParams, as_vector  # noqa: E402
from .chain import PlanarChain  # noqa: E402
from .urdf_robot import UrdfArm, UrdfRobot, from_urdf  # noqa: E402
from .registry import (  # noqa: E402
    ROBOTS,
    RobotEntry,
    RobotFactory,
    RobotSettings,
    find_robot,
    make_robot,
    register_robot,
    robot_config,
    robot_names,
    robot_params,
    robot_settings,
    unregister_robot,
)

__all__ = [
    "GRAVITY",
    "ROBOTS",
    "FiveBarState",
    "FloatArray",
    "LinkParams",
    "Manipulator",
    "Parallel5R",
    "PlanarChain",
    "RobotParams",
    "RobotEntry",
    "RobotFactory",
    "RobotSettings",
    "Serial3R",
    "as_vector",
    "find_robot",
    "make_robot",
    "register_robot",
    "robot_config",
    "robot_names",
    "robot_params",
    "robot_settings",
    "UrdfArm",
    "UrdfRobot",
    "from_urdf",
    "unregister_robot",
]
