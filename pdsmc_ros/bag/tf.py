"""``/tf`` and ``/tf_static`` for a bag, serialized with rosbags (no tf2_msgs wheel needed; ROS-free).

The recorder offers every joint state it receives; :class:`TfRecorder` keeps one per
``1 / rate`` of sim time (the states' header stamps) and turns it into a
``tf2_msgs/msg/TFMessage`` of the moving joints' link transforms
(:class:`~pdsmc_ros.robots.frames.LinkFrames`), so a bag opened in Foxglove or RViz
shows the arm moving. The fixed joints' transforms go once to ``/tf_static``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rosbags.typesys import Stores, get_typestore

from ..errors import CdrError
from ..robots.frames import LinkFrames, Transform
from .cdr import decode_joint_state_named, decode_stamp

TF_TYPE = "tf2_msgs/msg/TFMessage"
DEFAULT_TF_RATE = 50.0
"""Transforms per second of sim time in a bag (Foxglove interpolates between them)."""


class TfRecorder:
    """CDR ``TFMessage`` bytes from joint states, decimated in sim time.

    Parameters
    ----------
    urdf : str
        The arm's URDF (its ``/robot_description``).
    rate : float
        Transforms per second of sim time (> 0).
    """

    def __init__(self, urdf: str, *, rate: float = DEFAULT_TF_RATE) -> None:
        if not rate > 0.0:
            raise ValueError(f"rate must be > 0 transforms per second, got {rate!r}")
        self.frames = LinkFrames(urdf)
        self.period_ns = int(round(1e9 / rate))
        self.next_ns = 0
        self.store = get_typestore(Stores.ROS2_JAZZY)
        self.types = self.store.types

    def due(self, sec: int, nanosec: int) -> bool:
        """Whether the state stamped ``sec, nanosec`` is the next one to keep."""
        return sec * 1_000_000_000 + nanosec >= self.next_ns

    def message(self, sec: int, nanosec: int, names: Sequence[str], positions: Sequence[float]) -> bytes:
        """The moving joints' transforms at this state, and the next stamp :meth:`due` waits for."""
        now = sec * 1_000_000_000 + nanosec
        self.next_ns = (now // self.period_ns + 1) * self.period_ns
        return self._encode(sec, nanosec, self.frames.moving_transforms(dict(zip(names, positions, strict=False))))

    def messages(self, batch: Sequence[bytes]) -> list[bytes]:
        """``TFMessage`` bytes for the joint states of ``batch`` (raw CDR) that are due; a
        malformed state is skipped (the bag keeps it as received)."""
        out = []
        for data in batch:
            try:
                sec, nanosec = decode_stamp(data)
                if self.due(sec, nanosec):
                    names, sec, nanosec, position, _, _ = decode_joint_state_named(data)
                    out.append(self.message(sec, nanosec, names, position))
            except CdrError:
                continue
        return out

    def static_message(self) -> bytes:
        """The fixed joints' transforms (stamp 0: valid at every time)."""
        return self._encode(0, 0, self.frames.static())

    def _encode(self, sec: int, nanosec: int, transforms: list[Transform]) -> bytes:
        t: Any = self.types
        stamp = t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
        msgs = [
            t["geometry_msgs/msg/TransformStamped"](
                header=t["std_msgs/msg/Header"](stamp=stamp, frame_id=tr.parent),
                child_frame_id=tr.child,
                transform=t["geometry_msgs/msg/Transform"](
                    translation=t["geometry_msgs/msg/Vector3"](x=float(tr.translation[0]), y=float(tr.translation[1]),
                                                               z=float(tr.translation[2])),
                    rotation=t["geometry_msgs/msg/Quaternion"](x=float(tr.rotation[0]), y=float(tr.rotation[1]),
                                                               z=float(tr.rotation[2]), w=float(tr.rotation[3])),
                ),
            )
            for tr in transforms
        ]
        return bytes(self.store.serialize_cdr(t[TF_TYPE](transforms=msgs), TF_TYPE))
