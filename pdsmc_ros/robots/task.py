"""A task-space plane in an arm's workspace and the rotation helpers its inverse kinematics needs.

The thesis's contours are planar: ``(x, y)`` and, for the serial arm, the end
effector's pose angle in that plane. A spatial arm follows them in a
:class:`TaskPlane` -- an origin and two orthonormal in-plane axes -- so a contour
point ``(u, v)`` is the world point ``origin + u e_u + v e_v``, the pose is a
rotation about the plane's normal ``e_n = e_u x e_v``, and the contour error is
measured in the plane's coordinates with the thesis's formulas (Eqs. 2.9, 2.10).
numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from .base import FloatArray, as_vector
from .kernel_math import rotation_vector


@dataclass(frozen=True)
class TaskPlane:
    """A plane of the workspace: ``origin`` and the unit in-plane axes ``u``, ``v`` (base frame).

    Raises
    ------
    InvalidInputError
        If ``u`` and ``v`` are not orthonormal (to 1e-9).
    """

    origin: FloatArray
    u: FloatArray
    v: FloatArray

    def __post_init__(self) -> None:
        for label in ("origin", "u", "v"):
            object.__setattr__(self, label, as_vector(getattr(self, label), 3, f"plane {label}"))
        gram = np.array([[self.u @ self.u, self.u @ self.v], [self.u @ self.v, self.v @ self.v]])
        if not np.allclose(gram, np.eye(2), atol=1e-9):
            raise InvalidInputError(
                f"plane axes u = {self.u.tolist()} and v = {self.v.tolist()} must be orthonormal")

    @property
    def normal(self) -> FloatArray:
        return np.cross(self.u, self.v)

    @property
    def basis(self) -> FloatArray:
        """Rows ``e_u, e_v, e_n``: world vectors to plane components."""
        return np.stack([self.u, self.v, self.normal])

    def world(self, uv: FloatArray) -> FloatArray:
        """World points of plane coordinates ``uv`` ``(..., 2)``."""
        return self.origin + uv[..., :1] * self.u + uv[..., 1:2] * self.v

    def coordinates(self, x: FloatArray) -> FloatArray:
        """Plane coordinates ``(u, v)`` of world points ``x`` ``(..., 3)``."""
        d = x - self.origin
        return np.stack([d @ self.u, d @ self.v], axis=-1)

    @classmethod
    def facing_base(cls, point: ArrayLike) -> TaskPlane:
        """The vertical plane through ``point`` that faces the base: its ``u`` axis horizontal,
        ``v`` up (+z), its normal the horizontal direction from the base to ``point``."""
        p = as_vector(point, 3, "plane centre")
        out = np.array([p[0], p[1], 0.0])
        if np.hypot(p[0], p[1]) < 1e-6:
            out = np.array([1.0, 0.0, 0.0])  # above the base: face along x
        out /= np.linalg.norm(out)
        up = np.array([0.0, 0.0, 1.0])
        return cls(origin=p, u=np.cross(up, out), v=up)

    def describe(self) -> dict[str, list[float]]:
        return {"origin": self.origin.tolist(), "u": self.u.tolist(), "v": self.v.tolist()}


def axis_rotation(axis: FloatArray, angle: FloatArray) -> FloatArray:
    """Rotation matrices ``(..., 3, 3)`` by ``angle`` about the unit vector ``axis`` (Rodrigues)."""
    a = np.asarray(angle, dtype=float)[..., None, None]
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(a) * k + (1.0 - np.cos(a)) * (k @ k)


def rotation_log(r: FloatArray) -> FloatArray:
    """The rotation vector ``w`` with ``exp([w]x) = r`` (angle in [0, pi]) of one matrix
    (:func:`.kernel_math.rotation_vector`, the compiled form inverse kinematics uses)."""
    out = np.empty(3)
    rotation_vector(np.ascontiguousarray(r, dtype=float), out)
    return out
