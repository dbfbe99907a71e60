"""Joints by name: pick the controlled joints out of a JointState or JointTrajectory.

Every ROS consumer of ``/joint_states`` (robot_state_publisher, MoveIt,
ros2_control's controllers) matches joints by name: ros2_control's
joint_state_broadcaster does not publish in URDF order and some drivers publish
alphabetically. :class:`JointSelector` maps a message's ``name`` list to the
controller's ``joints`` -- any order, extra joints ignored -- and computes that
index permutation once per distinct name list, not per message (the lockstep
hot path decodes the same name tuple object for every message of one shape).

ROS-free: the nodes hand it decoded fields; it returns arrays or a one-line
reason naming the joint, never raises on message content.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..bag.cdr import decode_joint_state_named, decode_joint_trajectory_named
from ..errors import CdrError

FloatArray = np.ndarray
Values = Sequence[float] | np.ndarray
"""A column of the controlled joints: the decoded tuple itself on the short path, else an array."""

STATE_FIELDS = ("position", "velocity")  # a JointState's columns the controller reads
REFERENCE_FIELDS = ("positions", "velocities", "accelerations")  # a trajectory point's
_CACHE_SIZE = 16  # distinct name lists remembered (a source has one; a fuzzer endless ones)


class JointSelector:
    """The controlled joints' values out of named messages, in ``joints`` order.

    Parameters
    ----------
    joints : sequence of str
        The controlled joints, in the order of the control law's vectors.
    """

    def __init__(self, joints: Sequence[str]) -> None:
        self.joints = tuple(joints)
        self.n = len(self.joints)
        self._cache: dict[tuple[str, ...], tuple[np.ndarray | None, str]] = {}
        self._last_names: tuple[str, ...] | None = None
        self._last: tuple[np.ndarray | None, str] = (None, "")
        self._last_need = 0  # values a column needs for the last index

    def state_message(self, data: bytes, topic: str) -> tuple[int, int, tuple[Values, ...] | None, str]:
        """A serialized ``JointState``: ``(sec, nanosec, (q, qd), "")``, or ``(.., None, problem)``
        with a one-line problem naming ``topic``."""
        try:
            names, sec, nanosec, position, velocity, _ = decode_joint_state_named(data)
        except CdrError as exc:
            return 0, 0, None, f"malformed {topic} message ({exc})"
        arrays, problem = self.state(names, position, velocity)
        if problem:
            return sec, nanosec, None, f"{topic}: {problem}"
        return sec, nanosec, arrays, ""

    def reference_message(
        self, data: bytes, topic: str
    ) -> tuple[int, int, tuple[Values, ...] | None, str]:
        """A serialized one-point ``JointTrajectory`` (the reference stream), as :meth:`state_message`;
        ``(.., None, "")`` for a message without points."""
        try:
            decoded = decode_joint_trajectory_named(data)
        except CdrError as exc:
            return 0, 0, None, f"malformed {topic} message ({exc})"
        if decoded is None:
            return 0, 0, None, ""
        names, sec, nanosec, positions, velocities, accelerations = decoded
        arrays, problem = self.reference(names, positions, velocities, accelerations)
        if problem:
            return sec, nanosec, None, f"{topic}: {problem}"
        return sec, nanosec, arrays, ""

    def index(self, names: tuple[str, ...]) -> tuple[np.ndarray | None, str]:
        """``(index, "")`` with ``names[index[i]] == joints[i]``, or ``(None, reason)``.

        ``index`` is None with an empty reason when ``names`` starts with
        ``joints`` in order (the values are a plain prefix slice).
        """
        if names is self._last_names:
            return self._last
        found = self._cache.get(names)
        if found is None:
            found = self._match(names)
            if len(self._cache) >= _CACHE_SIZE:
                self._cache.clear()
            self._cache[names] = found
        self._last_names, self._last = names, found
        self._last_need = 0 if found[0] is None else int(found[0].max()) + 1
        return found

    def state(self, names: tuple[str, ...], position: Sequence[float],
              velocity: Sequence[float]) -> tuple[tuple[Values, ...], str]:
        """:meth:`select` of a JointState's ``position`` and ``velocity``.

        Once per control step: a message naming exactly ``joints``, in order, takes a short path
        that returns the columns themselves (the control law stacks all its inputs into one array).
        """
        n = self.n
        if len(position) == n and len(velocity) == n and names == self.joints:
            total = sum(position) + sum(velocity)
            if total - total == 0.0:  # NaN or inf makes the sum non-finite
                return (position, velocity), ""
        return self.select(names, STATE_FIELDS, position, velocity)

    def reference(self, names: tuple[str, ...], positions: Sequence[float], velocities: Sequence[float],
                  accelerations: Sequence[float]) -> tuple[tuple[Values, ...], str]:
        """:meth:`select` of a one-point JointTrajectory's positions, velocities and accelerations
        (the short path of :meth:`state`)."""
        n = self.n
        if len(positions) == n and len(velocities) == n and len(accelerations) == n and names == self.joints:
            total = sum(positions) + sum(velocities) + sum(accelerations)
            if total - total == 0.0:
                return (positions, velocities, accelerations), ""
        return self.select(names, REFERENCE_FIELDS, positions, velocities, accelerations)

    def _match(self, names: tuple[str, ...]) -> tuple[np.ndarray | None, str]:
        if names[: self.n] == self.joints:
            return None, ""
        position: dict[str, int] = {}
        for i, joint in enumerate(names):
            position.setdefault(joint, i)  # a repeated name: the first one counts
        missing = [j for j in self.joints if j not in position]
        if missing:
            return None, f"joint {missing[0]!r} missing (message names: {list(names)})" if len(missing) == 1 \
                else f"joints {missing} missing (message names: {list(names)})"
        return np.array([position[j] for j in self.joints], dtype=np.intp), ""

    def select(self, names: tuple[str, ...], fields: tuple[str, ...],
               *columns: Sequence[float]) -> tuple[tuple[FloatArray, ...], str]:
        """The controlled joints' values of each column (``fields`` names them, for errors).

        Returns ``(arrays, "")`` (a tuple, one array per column, in ``joints`` order),
        or ``((), reason)`` when a joint is missing, a
        column is shorter than the name list needs, or a value is not finite; the
        reason names the joint and the field. On the control loop's path once per
        message: the checks are a few Python builtins over the short tuples.
        """
        if names is self._last_names:
            index, reason = self._last
        else:
            index, reason = self.index(names)
        if reason:
            return (), reason
        # NaN or inf anywhere makes a sum non-finite; a column too short, a NaN of an extra
        # joint or finite values whose sum overflows are sorted out by the exact check. (Python
        # sums of the short tuples and one numpy call per column: a 2-D array and its rows
        # cost more.)
        need = self.n if index is None else self._last_need  # self.index() just cached it
        total = 0.0
        for column in columns:
            if len(column) < need:
                total = math.nan
                break
            total += sum(column)
        if total - total != 0.0:
            reason = self._problem(names, index, fields, columns)
            if reason:
                return (), reason
        if index is None:
            return tuple([np.array(column[:need]) for column in columns]), ""
        return tuple([np.array(column)[index] for column in columns]), ""

    def _problem(self, names: tuple[str, ...], index: np.ndarray | None, fields: tuple[str, ...],
                 columns: Sequence[Sequence[float]]) -> str:
        """Why the columns cannot be used, or "" (the quick check's false alarm)."""
        positions = range(self.n) if index is None else [int(i) for i in index]
        for field, values in zip(fields, columns):
            for joint, i in zip(self.joints, positions):
                if i >= len(values):
                    return (f"{field} has {len(values)} values for {len(names)} names "
                            f"(joint {joint!r} has none)")
                if not math.isfinite(values[i]):
                    return f"{field} of joint {joint!r} is not finite ({values[i]})"
        return ""
