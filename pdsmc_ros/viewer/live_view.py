"""What the live viewer shows, from the loop's messages (ROS-free; Foxglove's SDK for the wire).

:class:`LiveView` keeps the newest state, reference and command it is given and, when
asked (at the display rate, in wall time), turns them into one :class:`Frame`: the
arm's link transforms (:class:`~pdsmc_ros.robots.frames.LinkFrames`), the desired and
actual end-effector points in the base frame with their recent paths, and the joint
errors, contour error (the thesis's formulas, :meth:`Contour.contour_error`) and
torques. :class:`FoxgloveView` serves frames over the Foxglove WebSocket protocol
(foxglove-sdk): channels ``/tf`` (``foxglove.FrameTransforms``), ``/robot_description``
(``std_msgs/msg/String`` as JSON, for the 3D panel's URDF layer), ``/end_effector/paths``
(``foxglove.SceneUpdate``) and ``/pdsmc/errors`` (JSON, ready to plot).
"""

from __future__ import annotations

import json
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..bag.stamps import stamp_step, step_stamp
from ..robots.base import FloatArray
from ..robots.frames import LinkFrames, Transform
from ..runs.builder import RunSpec

PATH_POINTS = 2000
"""End-effector points kept per path (the oldest dropped)."""
CHANNELS = ("/tf", "/robot_description", "/end_effector/paths", "/pdsmc/errors")
ERRORS_SCHEMA = {
    "type": "object",
    "properties": {
        "sim_time": {"type": "number"}, "step": {"type": "integer"},
        "joint_error": {"type": "array", "items": {"type": "number"}},
        "contour_error": {"type": "number"},
        "torque": {"type": "array", "items": {"type": "number"}},
    },
}
STRING_SCHEMA = {"type": "object", "properties": {"data": {"type": "string"}}}


@dataclass(frozen=True)
class Frame:
    """One displayed moment."""

    step: int
    sim_time: float
    transforms: list[Transform]
    actual: FloatArray  # end effector, base frame (3)
    desired: FloatArray
    joint_error: list[float]
    contour_error: float
    torque: list[float]


class LiveView:
    """The newest loop messages, turned into a :class:`Frame` on demand.

    Parameters
    ----------
    spec : RunSpec
        The run watched (robot, contour, rate).
    """

    def __init__(self, spec: RunSpec) -> None:
        self.spec = spec
        self.robot = spec.robot_model()
        self.contour = spec.contour_model()
        self.urdf = spec.robot_description()
        self.frames = LinkFrames(self.urdf)
        self.static = self.frames.static()
        self.n = self.robot.n
        self.state: tuple[int, dict[str, float], FloatArray] | None = None
        # the run's references, computed as the trajectory node computes them (bit-identical):
        # the viewer need not take the stream of references sent ahead
        self.reference = spec.reference()
        self.torque: list[float] = [0.0] * self.n
        self.shown = -1
        self.actual_path: deque[FloatArray] = deque(maxlen=PATH_POINTS)
        self.desired_path: deque[FloatArray] = deque(maxlen=PATH_POINTS)

    def add_state(self, sec: int, nanosec: int, names: Sequence[str], positions: Sequence[float]) -> None:
        step = stamp_step(sec, nanosec, self.spec.rate)
        by_name = dict(zip(names, positions, strict=False))
        q = np.array([by_name.get(name, np.nan) for name in self.robot.joint_names])
        self.state = (step, by_name, q)

    def add_effort(self, values: Sequence[float]) -> None:
        self.torque = [float(v) for v in values][: self.n]

    def world(self, xy: FloatArray) -> FloatArray:
        """Base-frame point of a task-plane point (the thesis arms' plane is the URDF's x-z)."""
        return self.robot.plane_to_base(xy)

    def frame(self) -> Frame | None:
        """The newest state as a frame, or None if there is none newer than the last shown."""
        if self.state is None or self.state[0] == self.shown:
            return None
        step, by_name, q = self.state
        self.shown = step
        t = step / self.spec.rate
        finite = bool(np.all(np.isfinite(q)))
        xy = self.robot.position(q) if finite else np.full(2, np.nan)
        actual = self.world(xy)
        reference = self.reference.sample(np.array([t])).q[0]  # held at its end after the duration
        desired = self.world(self.robot.position(reference))
        joint_error = (reference - q).tolist()
        contour_error = float(self.contour.contour_error(np.array([t]), xy[None, :])[0]) if finite else float("nan")
        if finite:
            self.actual_path.append(actual)
        self.desired_path.append(desired)
        return Frame(step, t, self.static + self.frames.moving_transforms(by_name), actual, desired, joint_error,
                     contour_error, list(self.torque))


class FoxgloveView:
    """A Foxglove WebSocket server streaming :class:`Frame` s (see the module docstring).

    Parameters
    ----------
    view : LiveView
        Where frames come from.
    host, port : str, int
        Where the server listens (``ws://host:port``; port 0: any free port).
    """

    def __init__(self, view: LiveView, *, host: str = "127.0.0.1", port: int = 8765) -> None:
        import foxglove
        from foxglove import channels

        self.view = view
        self.server = foxglove.start_server(name="pdsmc_ros viewer", host=host, port=port)
        self.port = self.server.port
        self.tf = channels.FrameTransformsChannel("/tf")
        self.paths = channels.SceneUpdateChannel("/end_effector/paths")
        self.description = foxglove.Channel(
            "/robot_description", message_encoding="json",
            schema=foxglove.Schema(name="std_msgs/msg/String", encoding="jsonschema",
                                   data=json.dumps(STRING_SCHEMA).encode()))
        self.errors = foxglove.Channel(
            "/pdsmc/errors", message_encoding="json",
            schema=foxglove.Schema(name="pdsmc_ros/Errors", encoding="jsonschema",
                                   data=json.dumps(ERRORS_SCHEMA).encode()))
        self.root = view.frames.root
        self.frames_sent = 0

    def publish(self, frame: Frame, log_time: int) -> None:
        """Log one frame on every channel (the description too: a late client gets it)."""
        from foxglove import messages as m

        sec, nanosec = step_stamp(frame.step, self.view.spec.rate)
        stamp = m.Timestamp(sec, nanosec)
        self.tf.log(m.FrameTransforms(transforms=[
            m.FrameTransform(timestamp=stamp, parent_frame_id=t.parent, child_frame_id=t.child,
                             translation=m.Vector3(x=float(t.translation[0]), y=float(t.translation[1]),
                                                   z=float(t.translation[2])),
                             rotation=m.Quaternion(x=float(t.rotation[0]), y=float(t.rotation[1]),
                                                   z=float(t.rotation[2]), w=float(t.rotation[3])))
            for t in frame.transforms]), log_time=log_time)
        self.description.log({"data": self.view.urdf}, log_time=log_time)
        lines = [self._line(self.view.desired_path, (0.2, 0.4, 1.0, 1.0)),
                 self._line(self.view.actual_path, (1.0, 0.3, 0.2, 1.0))]
        self.paths.log(m.SceneUpdate(entities=[m.SceneEntity(timestamp=stamp, frame_id=self.root, id="end_effector",
                                                             lines=[line for line in lines if line is not None])]),
                       log_time=log_time)
        self.errors.log(_finite({"sim_time": frame.sim_time, "step": frame.step, "joint_error": frame.joint_error,
                                 "contour_error": frame.contour_error, "torque": frame.torque}), log_time=log_time)
        self.frames_sent += 1

    @staticmethod
    def _line(points: deque[FloatArray], rgba: tuple[float, float, float, float]) -> Any:
        from foxglove import messages as m

        if len(points) < 2:
            return None
        return m.LinePrimitive(type=m.LinePrimitiveLineType.LineStrip, thickness=0.004,
                               color=m.Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
                               points=[m.Point3(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in points])

    def close(self) -> None:
        self.server.stop()


def _finite(data: dict[str, Any]) -> dict[str, Any]:
    """JSON has no NaN: not-yet-known values as null."""
    def clean(value: Any) -> Any:
        if isinstance(value, float):
            return value if np.isfinite(value) else None
        if isinstance(value, list):
            return [clean(v) for v in value]
        return value
    return {k: clean(v) for k, v in data.items()}
