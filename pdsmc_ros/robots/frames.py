"""The link frames of a URDF for a joint state, as robot_state_publisher computes them (numpy only).

Each URDF joint places its child link in its parent link: the joint's ``<origin>``
(``xyz``, then ``rpy`` as fixed-axis roll, pitch, yaw) followed by its motion -- a
rotation by the joint value about ``<axis>`` (revolute, continuous) or a translation
along it (prismatic). :class:`LinkFrames` gives those parent-to-child transforms as
translations and unit quaternions ``(x, y, z, w)``, the fields of
``geometry_msgs/TransformStamped`` and of Foxglove's ``FrameTransform``: what ``/tf``
carries in a bag and what the live viewer streams. Works for any URDF tree (the
five-bar's open tree included), with no Pinocchio.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from xml.etree import ElementTree

import numpy as np

from ..errors import InvalidInputError
from .base import FloatArray

MOVING = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class Transform:
    """One parent-to-child transform: ``translation`` (m) and ``rotation`` quaternion ``(x, y, z, w)``."""

    parent: str
    child: str
    translation: FloatArray
    rotation: FloatArray


@dataclass(frozen=True)
class _Joint:
    name: str
    kind: str
    parent: str
    child: str
    origin: FloatArray  # 4 x 4
    axis: FloatArray


def _vector(text: str | None, default: tuple[float, float, float], what: str) -> FloatArray:
    if text is None:
        return np.array(default, dtype=float)
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        raise InvalidInputError(f"URDF {what}: expected 3 numbers, got {text!r}") from None
    if values.shape != (3,) or not np.all(np.isfinite(values)):
        raise InvalidInputError(f"URDF {what}: expected 3 finite numbers, got {text!r}")
    return values


def rpy_matrix(rpy: FloatArray) -> FloatArray:
    """URDF's fixed-axis roll, pitch, yaw: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def quaternion(r: FloatArray) -> FloatArray:
    """Unit quaternion ``(x, y, z, w)`` of a rotation matrix (Shepperd's method, ``w >= 0``)."""
    trace = r[0, 0] + r[1, 1] + r[2, 2]
    if trace > 0.0:
        s = 2.0 * np.sqrt(1.0 + trace)
        q = np.array([(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, s / 4.0])
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = np.empty(4)
        q[i] = s / 4.0
        q[j] = (r[j, i] + r[i, j]) / s
        q[k] = (r[k, i] + r[i, k]) / s
        q[3] = (r[k, j] - r[j, k]) / s
    q /= np.linalg.norm(q)
    return q if q[3] >= 0.0 else -q


class LinkFrames:
    """Parent-to-child link transforms of a URDF (see the module docstring).

    Raises
    ------
    InvalidInputError
        If the URDF does not parse or a joint lacks its parent or child.
    """

    def __init__(self, urdf: str) -> None:
        try:
            root = ElementTree.fromstring(urdf)
        except ElementTree.ParseError as exc:
            raise InvalidInputError(f"URDF does not parse: {exc}") from None
        joints = []
        for element in root.findall("joint"):  # not a <transmission>'s <joint>
            name = element.get("name", "")
            parent, child = element.find("parent"), element.find("child")
            if parent is None or child is None:
                raise InvalidInputError(f"URDF joint {name!r}: needs a parent and a child link")
            origin = element.find("origin")
            xyz = _vector(origin.get("xyz") if origin is not None else None, (0.0, 0.0, 0.0), f"joint {name!r} xyz")
            rpy = _vector(origin.get("rpy") if origin is not None else None, (0.0, 0.0, 0.0), f"joint {name!r} rpy")
            axis_element = element.find("axis")
            axis = _vector(axis_element.get("xyz") if axis_element is not None else None, (1.0, 0.0, 0.0),
                           f"joint {name!r} axis")
            placement = np.eye(4)
            placement[:3, :3] = rpy_matrix(rpy)
            placement[:3, 3] = xyz
            norm = float(np.linalg.norm(axis))
            joints.append(_Joint(name, element.get("type", "fixed"), parent.get("link", ""), child.get("link", ""),
                                 placement, axis / norm if norm > 0.0 else axis))
        self._joints = tuple(joints)
        self.moving = tuple(j.name for j in joints if j.kind in MOVING)
        children = {j.child for j in joints}
        links = [link.get("name", "") for link in root.findall("link")]
        self.root = next((link for link in links if link not in children), links[0] if links else "")

    def static(self) -> list[Transform]:
        """Transforms of the fixed joints (``/tf_static``)."""
        return [self._transform(j, j.origin) for j in self._joints if j.kind not in MOVING]

    def moving_transforms(self, positions: Mapping[str, float]) -> list[Transform]:
        """Transforms of the moving joints at ``positions`` (by joint name; a missing joint at 0)."""
        out = []
        for joint in self._joints:
            if joint.kind not in MOVING:
                continue
            value = float(positions.get(joint.name, 0.0))
            motion = np.eye(4)
            if joint.kind == "prismatic":
                motion[:3, 3] = joint.axis * value
            else:
                a = joint.axis
                k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
                motion[:3, :3] = np.eye(3) + np.sin(value) * k + (1.0 - np.cos(value)) * (k @ k)
            out.append(self._transform(joint, joint.origin @ motion))
        return out

    @staticmethod
    def _transform(joint: _Joint, matrix: FloatArray) -> Transform:
        return Transform(joint.parent, joint.child, matrix[:3, 3].copy(), quaternion(matrix[:3, :3]))


def compose(transforms: list[Transform], root: str) -> dict[str, FloatArray]:
    """Each link's 4 x 4 placement in ``root`` (for tests and checks), from parent-to-child transforms."""
    by_child = {t.child: t for t in transforms}
    placed: dict[str, FloatArray] = {root: np.eye(4)}

    def place(link: str) -> FloatArray:
        if link not in placed:
            t = by_child[link]
            x, y, z, w = t.rotation
            r = np.array([
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ])
            local = np.eye(4)
            local[:3, :3], local[:3, 3] = r, t.translation
            placed[link] = place(t.parent) @ local
        return placed[link]

    for child in by_child:
        place(child)
    return placed
