"""Robots: one module per robot (numpy model and compiled form side by side) and a registry.

Adding a robot: a module here with a :class:`Manipulator` subclass decorated with
:func:`register_robot`, its entry in ``config/robots.yaml``, an import below, and --
if it has a compiled form -- one dispatch line per function in :mod:`.compiled`.
A robot without a compiled form runs on the numpy path.
"""

# the thesis's robots register in its order (serial first): the order of every robot listing
from .serial_3r import Serial3R  # noqa: I001
from .parallel_5r import FiveBarState, Parallel5R
from .base import GRAVITY, FloatArray, LinkParams, Manipulator, RobotParams, as_vector
from .chain import PlanarChain
from .urdf_robot import UrdfRobot, from_urdf
from .registry import (
    ROBOTS,
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
    "RobotSettings",
    "Serial3R",
    "as_vector",
    "make_robot",
    "register_robot",
    "robot_config",
    "robot_names",
    "robot_params",
    "robot_settings",
    "UrdfRobot",
    "from_urdf",
    "unregister_robot",
]
