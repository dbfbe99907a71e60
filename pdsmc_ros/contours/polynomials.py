"""Polynomial time scalings: the thesis's quintic (Eqs. 4.3-4.5) and joint_trajectory_controller's
segments between two points (linear, cubic or quintic by the boundary values given)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..robots.base import FloatArray


def quintic(t: ArrayLike, duration: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Fifth-order time scaling and its derivatives, Eqs. (4.3)-(4.4).

    ``t`` is clipped to ``[0, duration]``: before the start and after the end
    the scaling rests at 0 or 1 with zero rate and acceleration.
    """
    tau = np.clip(np.asarray(t, dtype=float) / duration, 0.0, 1.0)
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
    sd = (30.0 * tau**2 - 60.0 * tau**3 + 30.0 * tau**4) / duration
    sdd = (60.0 * tau - 180.0 * tau**2 + 120.0 * tau**3) / duration**2
    return s, sd, sdd


def segment(t: float | FloatArray, duration: float, p0: FloatArray, v0: FloatArray | None, a0: FloatArray | None,
             p1: FloatArray, v1: FloatArray | None, a1: FloatArray | None
             ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Position, velocity and acceleration ``t`` s into a segment of ``duration`` s from
    ``(p0, v0, a0)`` to ``(p1, v1, a1)``: quintic when both ends give velocities and
    accelerations, cubic when both give velocities, linear in position otherwise (as
    ros2_controllers' ``interpolate_between_points``)."""
    if v0 is None or v1 is None:  # positions only (at either end): linear
        velocity = (p1 - p0) / duration
        return p0 + velocity * t, velocity, np.zeros_like(p0)
    if a0 is None or a1 is None:  # velocities at both ends: cubic
        T = duration
        c2 = (3.0 * (p1 - p0) - (2.0 * v0 + v1) * T) / T**2
        c3 = (2.0 * (p0 - p1) + (v0 + v1) * T) / T**3
        return (p0 + v0 * t + c2 * t**2 + c3 * t**3,
                v0 + 2.0 * c2 * t + 3.0 * c3 * t**2,
                2.0 * c2 + 6.0 * c3 * t)
    T = duration
    T2, T3, T4, T5 = T**2, T**3, T**4, T**5
    c3 = (20.0 * (p1 - p0) - (8.0 * v1 + 12.0 * v0) * T - (3.0 * a0 - a1) * T2) / (2.0 * T3)
    c4 = (30.0 * (p0 - p1) + (14.0 * v1 + 16.0 * v0) * T + (3.0 * a0 - 2.0 * a1) * T2) / (2.0 * T4)
    c5 = (12.0 * (p1 - p0) - (6.0 * v1 + 6.0 * v0) * T - (a0 - a1) * T2) / (2.0 * T5)
    return (p0 + v0 * t + 0.5 * a0 * t**2 + c3 * t**3 + c4 * t**4 + c5 * t**5,
            v0 + a0 * t + 3.0 * c3 * t**2 + 4.0 * c4 * t**3 + 5.0 * c5 * t**4,
            a0 + 6.0 * c3 * t + 12.0 * c4 * t**2 + 20.0 * c5 * t**3)
