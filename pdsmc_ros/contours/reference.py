"""A contour's continuous (unwrapped) joint references ``q_d, qd_d, qdd_d`` through the robot's
inverse kinematics and Jacobians (Section 4.2)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError, UnreachableError
from ..robots.base import Manipulator
from .joint_paths import JointPathContour
from .samples import JointSample
from .shapes import Contour

MAX_GRID_INTERVALS = 200_000
"""The grid's intervals at the most: ``grid_rate`` over the first 100 s of a contour, sparser in time
beyond (a contour slowed to an hour keeps the 100 s contour's density along its path, and 10 MB of
grid for a six-joint arm instead of 350)."""


class JointReference:
    """Continuous joint references of a contour for one robot.

    The path is solved once on a dense grid (:meth:`Manipulator.ik_path`, continuous
    along the motion); the reference at time ``t`` is the solution nearest the
    grid's, interpolated at ``t`` (:meth:`Manipulator.ik_near`: the branch offset of
    a closed-form solution, or the seed of a numerical one). The result at a given
    ``t`` therefore does not depend on which instants were asked before, so a node
    and the in-process simulator agree exactly.

    Raises
    ------
    UnreachableError
        At construction, naming the first unreachable point and its time.
    """

    def __init__(self, robot: Manipulator, contour: Contour, *, grid_rate: float = 2000.0) -> None:
        self.robot = robot
        self.contour = contour
        if isinstance(contour, JointPathContour):
            return  # joint-space via points: no inverse kinematics (see sample)
        if contour.dim != robot.task_dim:
            raise InvalidInputError(
                f"contour {contour.name!r} has {contour.dim} task coordinates, "
                f"{robot.name} needs {robot.task_dim}"
            )
        count = min(max(int(np.ceil(contour.duration * grid_rate)), 200), MAX_GRID_INTERVALS) + 1
        self._grid_t = np.linspace(0.0, contour.duration, count)
        p = contour.task(self._grid_t).p
        self._grid_q, ok = robot.ik_path(p)
        if not np.all(ok):
            first = int(np.argmin(ok))
            raise UnreachableError(
                f"contour {contour.name!r} leaves the {robot.name} workspace at "
                f"t = {self._grid_t[first]:.4f} s, point "
                f"{np.array2string(p[first], precision=4)}"
            )

    @property
    def duration(self) -> float:
        return self.contour.duration

    def sample(self, t: ArrayLike) -> JointSample:
        """``q_d, qd_d, qdd_d`` at times ``t`` (held at the end after ``duration``)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if isinstance(self.contour, JointPathContour):
            return self.contour.path.sample(t)
        task = self.contour.task(t)
        guide = np.stack(
            [np.interp(t, self._grid_t, self._grid_q[:, i]) for i in range(self.robot.n)], axis=-1
        )
        q = self.robot.ik_near(task.p, guide)
        qd, qdd = self.robot.joint_rates(q, task.pd, task.pdd)
        return JointSample(q=q, qd=qd, qdd=qdd)

