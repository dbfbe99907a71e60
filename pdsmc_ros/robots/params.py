"""A robot's parameters: links, motors and limits (Tables 4.1 and 4.2, ``config/robots.yaml``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import InvalidInputError

GRAVITY = 9.81
"""Gravitational acceleration (m/s^2), acting along -y."""

FloatArray = NDArray[np.float64]


# --------------------------------------------------------------------------- #
# Planar serial chain
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class LinkParams:
    """Structural parameters of one link (Tables 4.1 and 4.2).

    Attributes
    ----------
    mass : float
        Link mass (kg).
    length : float
        Joint-to-joint length (m).
    com : float
        Distance of the mass centre from the proximal joint, along the link (m).
    inertia : float
        Moment of inertia about the mass centre (kg m^2).
    """

    mass: float
    length: float
    com: float
    inertia: float

    def __post_init__(self) -> None:
        for name in ("mass", "length", "com", "inertia"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0.0:
                raise InvalidInputError(f"link {name} must be a finite number >= 0, got {value!r}")
        if self.length <= 0.0:
            raise InvalidInputError(f"link length must be > 0, got {self.length!r}")


# --------------------------------------------------------------------------- #
# Robot parameters
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class RobotParams:
    """Structural and motor parameters of a manipulator.

    Attributes
    ----------
    links : tuple of LinkParams
        Links in thesis numbering (Tables 4.1, 4.2).
    motor_inertia, motor_damping : float
        ``J_i`` (kg m^2) and ``B_i`` (N m s) of every actuated joint.
    base_length : float
        ``L5`` of the five-bar (m); unused by the serial arm.
    gravity : float
        Gravity along -y (m/s^2).
    effort_limit, velocity_limit : tuple of float
        Per actuated joint: the largest torque (N m) and rate (rad/s); empty: unknown (unlimited).
    position_limit : tuple of (float, float)
        Per actuated joint: lower and upper angle (rad); empty: unlimited (the planar arms'
        joints turn freely).
    """

    links: tuple[LinkParams, ...]
    motor_inertia: float
    motor_damping: float
    base_length: float = 0.0
    gravity: float = GRAVITY
    effort_limit: tuple[float, ...] = ()
    velocity_limit: tuple[float, ...] = ()
    position_limit: tuple[tuple[float, float], ...] = ()

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], *, name: str = "robot") -> RobotParams:
        """Build from a YAML-style mapping (see ``config/robots.yaml``)."""
        try:
            links = tuple(
                LinkParams(
                    mass=float(link["mass"]),
                    length=float(link["length"]),
                    com=float(link["com"]),
                    inertia=float(link["inertia"]),
                )
                for link in data["links"]
            )
            limits = data.get("limits") or {}
            return cls(
                links=links,
                motor_inertia=float(data["motor_inertia"]),
                motor_damping=float(data["motor_damping"]),
                base_length=float(data.get("base_length", 0.0)),
                gravity=float(data.get("gravity", GRAVITY)),
                effort_limit=tuple(float(v) for v in limits.get("effort") or ()),
                velocity_limit=tuple(float(v) for v in limits.get("velocity") or ()),
                position_limit=tuple((float(lo), float(hi)) for lo, hi in limits.get("position") or ()),
            )
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InvalidInputError(f"{name}: malformed robot parameters ({exc})") from exc


def joint_limits(params: RobotParams, n: int, name: str) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(effort, velocity, position)`` limits of ``params`` for ``n`` actuated joints (unknown: infinite).

    Raises
    ------
    InvalidInputError
        If a limit list does not have ``n`` entries, a magnitude is not > 0, or a lower
        position limit is not below its upper one.
    """
    effort = np.full(n, np.inf)
    velocity = np.full(n, np.inf)
    position = np.tile([-np.inf, np.inf], (n, 1))
    for label, given, out in (("effort", params.effort_limit, effort), ("velocity", params.velocity_limit, velocity)):
        if not given:
            continue
        values = np.asarray(given, dtype=float)
        if values.shape != (n,) or np.any(np.isnan(values)) or np.any(values <= 0.0):
            raise InvalidInputError(f"{name}: limits.{label} needs {n} values > 0 (one per actuated joint), "
                                    f"got {list(given)}")
        out[:] = values
    if params.position_limit:
        pairs = np.asarray(params.position_limit, dtype=float)
        if pairs.shape != (n, 2) or np.any(np.isnan(pairs)) or np.any(pairs[:, 0] >= pairs[:, 1]):
            raise InvalidInputError(f"{name}: limits.position needs {n} pairs [lower, upper] with lower < upper "
                                    f"(rad), got {[list(p) for p in params.position_limit]}")
        position[:] = pairs
    return effort, velocity, position


def motor_array(value: float | FloatArray, n: int) -> FloatArray:
    return np.asarray(value, dtype=float)[..., None] * np.ones(n)
