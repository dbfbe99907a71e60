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

from .errors import ConfigError

FloatArray = np.ndarray

_CACHE_SIZE = 16  # distinct name lists remembered (a source has one; a fuzzer endless ones)


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
        return found

    def _match(self, names: tuple[str, ...]) -> tuple[np.ndarray | None, str]:
        if names[: self.n] == self.joints:
            return None, ""
        position = {}
        for i, joint in enumerate(names):
            position.setdefault(joint, i)  # a repeated name: the first one counts
        missing = [j for j in self.joints if j not in position]
        if missing:
            return None, f"joint {missing[0]!r} missing (message names: {list(names)})" if len(missing) == 1 \
                else f"joints {missing} missing (message names: {list(names)})"
        return np.array([position[j] for j in self.joints], dtype=np.intp), ""

    def select(self, names: tuple[str, ...],
               *columns: tuple[tuple[str, Sequence[float]], ...]) -> tuple[list[FloatArray], str]:
        """The controlled joints' values of each ``(field name, values)`` column.

        Returns ``(arrays, "")``, or ``([], reason)`` when a joint is missing, a
        column is shorter than the name list needs, or a value is not finite; the
        reason names the joint and the field.
        """
        index, reason = self.index(names)
        if reason:
            return [], reason
        arrays = []
        need = self.n if index is None else self._required(index)
        for field, values in columns:
            if len(values) < need:
                return [], (f"{field} has {len(values)} values for {len(names)} names "
                            f"(joint {self._first_uncovered(names, index, len(values))!r} has none)")
            array = np.array(values[: self.n]) if index is None else np.array(values)[index]
            total = float(array.sum())
            if total - total != 0.0:  # NaN or inf somewhere (or a sum overflowing: looked at below)
                bad = [self.joints[i] for i in range(self.n) if not math.isfinite(float(array[i]))]
                if bad:
                    return [], f"{field} of joint {bad[0]!r} is not finite ({float(array[self.joints.index(bad[0])])})"
            arrays.append(array)
        return arrays, ""

    @staticmethod
    def _required(index: np.ndarray) -> int:
        return int(index.max()) + 1

    def _first_uncovered(self, names: tuple[str, ...], index: np.ndarray | None, count: int) -> str:
        if index is None:
            return self.joints[count]
        for joint, i in zip(self.joints, index):
            if i >= count:
                return joint
        return self.joints[0]  # pragma: no cover - select only calls this when one is uncovered
