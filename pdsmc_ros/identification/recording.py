"""The joint states of a bag, matched to an arm's joints by name.

Any bag with ``sensor_msgs/JointState`` on ``/joint_states`` serves: a run recorded by the
project's recorder beside the MuJoCo stand-in or a real driver, or any rosbag2 MCAP bag. Joints
are matched by name, as every ROS consumer does (a driver may publish them in any order, and
more joints than the arm's: a gripper's). Times are the messages' header stamps (the receive
times where a driver leaves them zero).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..bag.cdr import decode_joint_state_named
from ..bag.mcapscan import scan
from ..errors import CdrError, InvalidInputError
from ..robots.base import FloatArray

__all__ = ["JointRecording", "RecordingError", "parse_window", "read_joint_states"]

TOPIC = "/joint_states"


class RecordingError(InvalidInputError):
    """A bag that cannot give an arm's joint states and efforts (one line: which bag and why)."""


@dataclass(frozen=True)
class JointRecording:
    """One bag's joint states in the arm's joint order.

    Attributes
    ----------
    t : ndarray, shape (k,)
        Seconds from the first state.
    q, qd, tau : ndarray, shape (k, n)
        Positions, velocities (NaN where the driver gave none) and efforts.
    bag_joints : tuple of str
        Every joint the bag's states name.
    """

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    tau: FloatArray
    bag_joints: tuple[str, ...]

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    def window(self, start: float, end: float, label: str) -> JointRecording:
        """The states from ``start`` to ``end`` s (from the first state), times from ``start``.

        Raises
        ------
        RecordingError
            One line naming ``label``: fewer than 3 states in the window.
        """
        inside = (self.t >= start) & (self.t <= end)
        if int(inside.sum()) < 3:
            raise RecordingError(f"{label}: the window {start:g}-{end:g} s holds {int(inside.sum())} joint states "
                                 f"(the bag's run is {self.duration:.3g} s long)")
        return JointRecording(self.t[inside] - start, self.q[inside], self.qd[inside], self.tau[inside],
                              self.bag_joints)


def parse_window(text: str, flag: str) -> tuple[float, float]:
    """``START:END`` (seconds from a bag's first state) as two floats.

    Raises
    ------
    InvalidInputError
        One line naming ``flag``: not two finite numbers, or ``END <= START``.
    """
    parts = text.split(":")
    try:
        start, end = (float(p) for p in parts) if len(parts) == 2 else (float("nan"), float("nan"))
    except ValueError:
        start, end = float("nan"), float("nan")
    if not (np.isfinite(start) and np.isfinite(end) and end > start >= 0.0):
        raise InvalidInputError(f"{flag} must be START:END in seconds from the bag's first state, 0 <= START < END; "
                                f"got {text!r}")
    return start, end


def read_joint_states(path: str | Path, joint_names: tuple[str, ...], *, topic: str = TOPIC) -> JointRecording:
    """The arm's joint states and efforts from the bag at ``path`` (a directory of ``.mcap`` files or
    one file).

    Raises
    ------
    RecordingError
        One line naming the bag: not a bag, no states on ``topic``, states without efforts,
        some of the arm's joints missing from them, or none of them (the arm does not match the
        bag: another robot's URDF).
    """
    label = f"bag {str(path)!r}"
    where = Path(path)
    if not where.exists():
        raise RecordingError(f"{label}: no such file or directory")
    files = sorted(where.glob("*.mcap")) if where.is_dir() else [where]
    if not files:
        raise RecordingError(f"{label}: no .mcap file in it")
    raws: list[bytes] = []
    received: list[int] = []
    for file in files:
        try:
            result = scan(file, [topic])
        except (OSError, ValueError) as exc:
            raise RecordingError(f"{label}: not a readable MCAP bag ({exc})") from None
        raws += result.messages[topic]
        received += result.log_times[topic]
    if not raws:
        raise RecordingError(f"{label} holds no {topic} (sensor_msgs/JointState): nothing to identify from")
    bag_joints: dict[str, int] = {}
    decoded = []
    for raw in raws:
        try:
            names, sec, nanosec, position, velocity, effort = decode_joint_state_named(raw)
        except CdrError:
            continue  # not a JointState of a known layout: skipped, as the analysis does
        for name in names:
            bag_joints.setdefault(name, len(bag_joints))
        decoded.append((tuple(names), sec + 1e-9 * nanosec, position, velocity, effort))
    if not decoded:
        raise RecordingError(f"{label}: no readable sensor_msgs/JointState on {topic}")
    known = tuple(bag_joints)
    missing = [j for j in joint_names if j not in bag_joints]
    if len(missing) == len(joint_names):
        raise RecordingError(f"{label}: the arm does not match the bag's joints: the URDF's are "
                             f"{', '.join(joint_names)}; the bag's {topic} names {', '.join(known)}")
    if missing:
        raise RecordingError(f"{label}: joints missing from the bag's {topic}: {', '.join(missing)} (it names "
                             f"{', '.join(known)})")
    k, n = len(decoded), len(joint_names)
    t = np.empty(k)
    q = np.full((k, n), np.nan)
    qd = np.full((k, n), np.nan)
    tau = np.full((k, n), np.nan)
    for s, (names, stamp, position, velocity, effort) in enumerate(decoded):
        t[s] = stamp
        where_in = {name: i for i, name in enumerate(names)}
        for j, joint in enumerate(joint_names):
            i = where_in.get(joint)
            if i is None:
                continue
            if i < len(position):
                q[s, j] = position[i]
            if i < len(velocity):
                qd[s, j] = velocity[i]
            if i < len(effort):
                tau[s, j] = effort[i]
    if np.all(t == 0.0):
        t = np.asarray(received, dtype=float)[: len(t)] * 1e-9
    if not np.any(np.isfinite(tau)):
        raise RecordingError(f"{label}: its {topic} carry no efforts (the effort field is empty): the driver must "
                             "report the joints' efforts for an identification")
    complete = np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(tau), axis=1)
    if not np.any(complete):
        raise RecordingError(f"{label}: no state of {topic} has every joint's position and effort")
    t, q, qd, tau = t[complete], q[complete], qd[complete], tau[complete]
    order = np.argsort(t, kind="stable")
    t, q, qd, tau = t[order], q[order], qd[order], tau[order]
    distinct = np.concatenate([[True], np.diff(t) > 0.0])  # a state published twice counts once
    t, q, qd, tau = t[distinct], q[distinct], qd[distinct], tau[distinct]
    return JointRecording(t - t[0], q, qd, tau, known)
