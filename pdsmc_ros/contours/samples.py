"""Sampled references: task-space points and joint-space references at a set of instants."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..robots.base import FloatArray


@dataclass(frozen=True)
class TaskSample:
    """Desired task point, rate and acceleration at a set of instants, ``(len(t), dim)``."""

    p: FloatArray
    pd: FloatArray
    pdd: FloatArray



@dataclass(frozen=True)
class JointSample:
    """Joint references at a set of instants, each ``(len(t), n)``."""

    q: FloatArray
    qd: FloatArray
    qdd: FloatArray

    def stacked(self) -> FloatArray:
        """``(len(t), 3, n)`` array: q, qd, qdd per instant (kernel layout)."""
        return np.stack([self.q, self.qd, self.qdd], axis=1)
