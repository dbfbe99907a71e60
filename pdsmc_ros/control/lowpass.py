"""The first-order low-pass of the drives' filters (ROS-free): one formula for the stand-in's drive
(:mod:`pdsmc_ros.sim.drive`) and the stability check that models its velocity filter
(:mod:`pdsmc_ros.control.stability`)."""

from __future__ import annotations

import math

import numpy as np

from ..robots.base import FloatArray


def lowpass_gain(dt: float | FloatArray, cutoff_hz: FloatArray | float) -> FloatArray:
    """libfranka's first-order low-pass gain ``dt / (dt + 1 / (2 pi f))`` per sample (1 where
    ``f`` is 0: no filter): ``y += a (x - y)`` each sample (``franka::lowpassFilter``)."""
    f = np.asarray(cutoff_hz, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(f > 0, dt / (dt + 1.0 / (2.0 * math.pi * np.where(f > 0, f, 1.0))), 1.0)
