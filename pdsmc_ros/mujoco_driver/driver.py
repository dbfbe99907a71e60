"""A robot driver around MuJoCo: brakes until the first command, then the latest command each step
(ROS-free; the ``mujoco_driver`` node wires it to topics).

What it models is a ros2_control robot driver with an effort controller
(``effort_controllers/JointGroupEffortController``): the command is one torque per joint,
matched by name; a command of the wrong length or with a non-finite value is dropped (the
forward command controller drops it too); the last command is applied until another arrives,
until ``command_timeout`` passes without one, after which the brakes close again (a real
driver's watchdog, :data:`DEFAULT_COMMAND_TIMEOUT_S` by default; ros2_control's forward command
controller has none: 0 models it). With the brakes closed
the arm is frozen where it is: MuJoCo does not step and the rates are zero. The physics
runs on the wall clock: each :meth:`MujocoDriver.advance` steps MuJoCo until its time
reaches the wall time (missed ticks are caught up, at most :data:`MAX_CATCH_UP_S` of them).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from ..parameters.tables import DEFAULT_COMMAND_TIMEOUT_S, JOINT_STATE_ORDERS
from ..robots.base import FloatArray
from ..sim.mujoco_model import MujocoArm, _mujoco, set_state

MAX_CATCH_UP_S = 0.1
"""The longest stretch of wall time one :meth:`MujocoDriver.advance` integrates; beyond it
(the process was stopped, say) the physics' clock jumps to the wall clock's."""


class MujocoDriver:
    """The simulated arm behind a driver.

    Parameters
    ----------
    arm : MujocoArm
        The MuJoCo model (:func:`pdsmc_ros.sim.mujoco_model.build_model`).
    q0 : array_like
        Initial angles of the actuated joints (robot order).
    passive0 : array_like, optional
        Initial angles of the passive joints (the five-bar's: those that close its loop at
        ``q0``, in the assembly the thesis uses; :func:`initial_passive`). Required when the
        arm has passive joints.
    command_joints : sequence of str, optional
        The joint each entry of a command drives (``data[i]`` -> ``command_joints[i]``);
        by default the arm's actuated joints in its order.
    command_timeout : float
        Seconds after the last command at which the brakes close again (default
        :data:`DEFAULT_COMMAND_TIMEOUT_S`); 0: never (the last command is held forever, as a
        forward command controller does).
    """

    def __init__(self, arm: MujocoArm, q0: ArrayLike, *, passive0: ArrayLike | None = None,
                 command_joints: Sequence[str] | None = None,
                 command_timeout: float = DEFAULT_COMMAND_TIMEOUT_S) -> None:
        self._mujoco = _mujoco()
        self.arm = arm
        self.data = arm.data()
        joints = tuple(arm.joint_names if command_joints is None else command_joints)
        unknown = [j for j in joints if j not in arm.joint_names]
        if unknown or len(set(joints)) != len(joints) or len(joints) != arm.n:
            raise InvalidInputError(
                f"joints must name each of the arm's {arm.n} actuated joints once ({', '.join(arm.joint_names)}), "
                f"got {list(joints)}")
        if not math.isfinite(command_timeout) or command_timeout < 0.0:
            raise InvalidInputError(f"command_timeout must be >= 0 s (0: none), got {command_timeout!r}")
        self.command_joints = joints
        self._order = np.array([arm.joint_names.index(j) for j in joints], dtype=np.intp)
        self.command_timeout = float(command_timeout)
        q = np.asarray(q0, dtype=float)
        if q.shape != (arm.n,) or not np.all(np.isfinite(q)):
            raise InvalidInputError(f"initial_positions must be {arm.n} finite angles (rad), got {q.tolist()}")
        _check_within_range(arm, q)
        set_state(arm, self.data, q)
        k = len(arm.passive_joint_names)
        if k:
            passive = np.zeros(0) if passive0 is None else np.asarray(passive0, dtype=float)
            if passive.shape != (k,) or not np.all(np.isfinite(passive)):
                raise InvalidInputError(f"initial_positions: the passive joints {list(arm.passive_joint_names)} "
                                        f"need {k} finite angles closing the loop, got {passive.tolist()}")
            self.data.qpos[arm.qpos[arm.n:]] = passive
        self._mujoco.mj_forward(arm.model, self.data)
        self.timestep = float(arm.model.opt.timestep)
        self.torque = np.zeros(arm.n)  # robot order
        self.braked = True
        self.clock = 0.0  # wall time (s, the caller's clock) the physics' state belongs to
        self.last_command = -math.inf
        self.commands = 0
        self.dropped = 0
        self.steps = 0
        self.skipped = 0.0  # wall seconds not integrated (beyond MAX_CATCH_UP_S)

    # -- commands ------------------------------------------------------------ #
    def command(self, values: Sequence[float], now: float) -> str | None:
        """Take a command (``values[i]`` for ``command_joints[i]``) at wall time ``now``.

        Returns None if it was taken, else why it was dropped (one line); a dropped command
        leaves the previous one in force. The first command releases the brakes.
        """
        if len(values) != self.arm.n:
            self.dropped += 1
            return (f"command dropped: {len(values)} values for {self.arm.n} joints "
                    f"({', '.join(self.command_joints)})")
        tau = np.asarray(values, dtype=float)
        if not np.all(np.isfinite(tau)):
            self.dropped += 1
            bad = int(np.argmin(np.isfinite(tau)))
            return f"command dropped: joint {self.command_joints[bad]!r} has a non-finite effort ({tau[bad]!r})"
        self.torque[self._order] = tau
        self.commands += 1
        self.last_command = now
        if self.braked:
            self.braked = False
            self.clock = now
        return None

    # -- the physics on the wall clock ------------------------------------- #
    def advance(self, now: float) -> bool:
        """Step MuJoCo until its state is that of wall time ``now`` (the brakes closed: not at
        all). Returns whether the brakes closed in this call (command timeout)."""
        if self.braked:
            self.clock = now
            return False
        if self.command_timeout and now - self.last_command > self.command_timeout:
            self.brake()
            self.clock = now
            return True
        behind = now - self.clock
        if behind > MAX_CATCH_UP_S:
            self.skipped += behind - MAX_CATCH_UP_S
            self.clock = now - MAX_CATCH_UP_S
            behind = MAX_CATCH_UP_S
        steps = int(behind / self.timestep + 0.5)
        if steps:
            m, d = self.arm.model, self.data
            d.ctrl[:] = self.torque
            for _ in range(steps):
                self._mujoco.mj_step(m, d)
            self.clock += steps * self.timestep
            self.steps += steps
        return False

    def brake(self) -> None:
        """Close the brakes: the arm stops where it is, the command is forgotten."""
        self.braked = True
        self.torque[:] = 0.0
        self.data.qvel[:] = 0.0
        self.data.ctrl[:] = 0.0
        self._mujoco.mj_forward(self.arm.model, self.data)

    # -- state ------------------------------------------------------------- #
    def state(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Positions, rates and efforts of ``arm.joint_names + arm.passive_joint_names``: the
        efforts are the motors' torques (after saturation; 0 with the brakes closed and on
        passive joints)."""
        d = self.data
        effort = np.zeros(len(self.arm.qpos))
        if not self.braked:
            effort[:self.arm.n] = d.actuator_force
        return d.qpos[self.arm.qpos].copy(), d.qvel[self.arm.dof].copy(), effort

    @property
    def model(self) -> Any:
        return self.arm.model


def _check_within_range(arm: MujocoArm, q: FloatArray) -> None:
    """Refuse start angles outside a joint's URDF ``<limit lower upper>``: MuJoCo makes those
    limits hard stops, so the first step would throw the joint back onto its stop (and a
    controller holding the angle it saw first would push against the stop at full torque).

    Raises
    ------
    InvalidInputError
        Naming the joint, the angle and its limits.
    """
    mujoco = _mujoco()
    for name, angle in zip(arm.joint_names, q):
        jid = mujoco.mj_name2id(arm.model, mujoco.mjtObj.mjOBJ_JOINT, name)
        lower, upper = (float(v) for v in arm.model.jnt_range[jid])
        if arm.model.jnt_limited[jid] and not lower <= angle <= upper:
            raise InvalidInputError(f"initial_positions: joint '{name}' at {angle:g} rad is outside its "
                                    f"limits [{lower:g}, {upper:g}] (the URDF's <limit lower upper>)")


def default_positions(robot: str) -> FloatArray:
    """Where the driver's arm starts unless told: a URDF arm's ``home`` (its options), a thesis
    arm at the start of its ``circle`` contour -- where the ``plant`` node starts it, so a
    thesis run against the driver begins without an initial error."""
    from ..contours import JointReference
    from ..robots.registry import make_robot
    from ..runs.builder import build_contour

    model = make_robot(robot)
    home = model.home_configuration()
    if home is not None:
        return home
    reference = JointReference(model, build_contour(robot, "circle"))
    return np.asarray(reference.sample([0.0]).q[0], dtype=float)


def initial_passive(robot: str, q0: ArrayLike) -> FloatArray:
    """The passive joints' angles that close a closed chain's loop at ``q0`` (the five-bar's, in
    the thesis's assembly: its closed-form kinematics, a state, not a model, handed to MuJoCo);
    empty for a serial arm."""
    from ..robots.registry import make_robot

    robot_model = make_robot(robot)
    q = np.asarray(q0, dtype=float)
    return np.asarray(robot_model.passive_joints(q, np.zeros_like(q))[0], dtype=float)




def joint_state_order(names: Sequence[str], order: str) -> list[int]:
    """Indices into ``names`` in the order ``/joint_states`` lists them: ``urdf`` (the
    description's), ``reversed``, or ``alphabetical`` (as some real drivers do; consumers
    must match joints by name)."""
    if order not in JOINT_STATE_ORDERS:
        raise InvalidInputError(
            f"parameter joint_state_order must be one of {', '.join(JOINT_STATE_ORDERS)}, got {order!r}")
    index = list(range(len(names)))
    if order == "reversed":
        return index[::-1]
    if order == "alphabetical":
        return sorted(index, key=lambda i: names[i])
    return index
