"""The ``joints`` parameter mapped by name onto the robot's joints (issue 29 item 4).

The control law's vectors are always in the robot's joint order (the order of
its model and of its preset gains). ``joints`` is the order the user speaks in:
the command's ``data``, gains and torque limits given as parameters, and every
per-joint output (feedback, controller state) follow it, as ros2_control's
controllers do with their ``joints`` parameter. States and references are matched
by name into robot order (:class:`~pdsmc_ros.controller.joints.JointSelector`). ROS-free.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import ConfigError

FloatArray = np.ndarray


def check_joint_names(joints: object, n: int, *, name: str = "joints") -> tuple[str, ...]:
    """Validate a ``joints`` parameter: ``n`` distinct, non-empty names.

    Raises
    ------
    ConfigError
        Naming the parameter and what is allowed.
    """
    if isinstance(joints, str) or not isinstance(joints, Sequence) \
            or not all(isinstance(j, str) for j in joints):
        raise ConfigError(f"parameter {name} must be a list of {n} joint names, got {joints!r}")
    names = tuple(joints)
    if len(names) != n or len(set(names)) != n or not all(names):
        raise ConfigError(
            f"parameter {name} needs {n} distinct non-empty joint names (one per actuated joint), "
            f"got {list(names)}")
    return names


class JointMap:
    """The user's ``joints`` order against the robot's.

    Parameters
    ----------
    robot_joints : sequence of str
        The robot's actuated joints, in the order of its model.
    joints : sequence of str
        The ``joints`` parameter: the same names in any order.

    Raises
    ------
    ConfigError
        A name the robot does not have (listing the robot's names), a repeated or
        missing one.
    """

    def __init__(self, robot_joints: Sequence[str], joints: object) -> None:
        self.robot_joints = tuple(robot_joints)
        n = len(self.robot_joints)
        self.joints = check_joint_names(joints, n)
        unknown = [name for name in self.joints if name not in self.robot_joints]
        if unknown:
            raise ConfigError(f"parameter joints: {unknown[0]!r} is not a joint of the robot; "
                              f"its actuated joints are {list(self.robot_joints)}")
        # user_of[i]: the robot index of joints[i]; a vector in joints order is robot[user_of]
        self.user_of = np.array([self.robot_joints.index(name) for name in self.joints], dtype=np.intp)
        self.robot_of = np.argsort(self.user_of)  # a vector in robot order is user[robot_of]
        self.identity = bool(np.all(self.user_of == np.arange(n)))

    def to_user(self, robot_vector: FloatArray) -> FloatArray:
        """A robot-order vector in ``joints`` order (the command's ``data``, per-joint outputs)."""
        return robot_vector if self.identity else robot_vector[self.user_of]

    def to_robot(self, user_vector: Sequence[float] | FloatArray) -> FloatArray:
        """A vector given in ``joints`` order (gains, limits as parameters) in robot order."""
        values = np.asarray(user_vector, dtype=float)
        return values if self.identity else values[self.robot_of]
