"""Robots: one module per robot (numpy model and compiled form side by side) and a registry.

Adding a robot: a :class:`Manipulator` subclass decorated with :func:`register_robot`
(here or in any module: a test registers its own) and its entry in ``config/robots.yaml``
(or the mapping given to :func:`register_robot`); a built-in one is imported below. A
robot without a compiled form runs behind :mod:`.python_form`'s; one with its own adds one
entry to :data:`.compiled.COMPILED`. A URDF arm is no class: an instance of
:class:`UrdfArm` (``robot:=`` a name of ``config/urdf_arms.yaml`` or a ``.urdf`` path).
"""

# before any kernel runs: drop cached kernels built from other sources (see kernel_cache)
from ..kernel_cache import refresh as _refresh_kernel_cache  # noqa: I001

_refresh_kernel_cache()

# the thesis's robots register in its order (serial first): the order of every robot listing
from .serial_3r import Serial3R  # noqa: E402, I001
from .parallel_5r import FiveBarState, Parallel5R  # noqa: E402
from .base import GRAVITY, FloatArray, LinkParams, Manipulator, RobotParams, as_vector  # noqa: E402
from .chain import PlanarChain  # noqa: E402
from .urdf_robot import UrdfArm, UrdfRobot, from_urdf  # noqa: E402
from .registry import (  # noqa: E402
    ROBOTS,
    RobotFactory,
    RobotSettings,
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
    "RobotFactory",
    "RobotSettings",
    "Serial3R",
    "as_vector",
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
