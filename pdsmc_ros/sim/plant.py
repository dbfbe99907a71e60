"""The plant of Eq. (4.1) advanced one control period at a time (what the plant node runs)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from ..robots import compiled as robot_compiled
from ..robots.base import FloatArray, Manipulator, as_vector
from .rk4 import compiled_step


class _StatePart:
    """``q`` or ``qd`` of :attr:`PlantStepper.state`: a view of it; assigning sets the values."""

    def __init__(self, index: int) -> None:
        self.index = index

    def __get__(self, stepper: PlantStepper, owner: type | None = None) -> FloatArray:
        return stepper._parts[self.index]

    def __set__(self, stepper: PlantStepper, value: ArrayLike) -> None:
        stepper._parts[self.index][:] = value


class PlantStepper:
    """The plant of Eq. (4.1) advanced one control period at a time.

    Parameters
    ----------
    robot : Manipulator
        Simulated robot (with payload if any).
    period : float
        Control period (s) over which each torque is held.
    q0, qd0 : array_like
        Initial joint angles and rates.
    """

    q = _StatePart(0)
    """Joint angles now (a view of :attr:`state`; assigning sets the values)."""
    qd = _StatePart(1)
    """Joint rates now (a view of :attr:`state`; assigning sets the values)."""

    def __init__(self, robot: Manipulator, period: float, q0: ArrayLike, qd0: ArrayLike) -> None:
        if not np.isfinite(period) or period <= 0.0:
            raise InvalidInputError(f"period must be > 0 s, got {period!r}")
        self.robot = robot
        self.period = float(period)
        self.kind, self.params = robot_compiled.pack(robot)
        self._step = compiled_step(self.kind)
        n = robot.n
        self.state = np.concatenate([as_vector(q0, n, "q0"), as_vector(qd0, n, "qd0")]).astype(float)
        self._parts = (self.state[:n], self.state[n:])  # views: step() advances the state in place
        self._work = robot_compiled.workspace(robot.n)
        self._outputs = np.zeros(robot_compiled.OUTPUTS_SIZE)
        self.steps = 0

    def step(self, tau: FloatArray) -> None:
        """Integrate one period with ``tau`` held (RK4, :mod:`pdsmc_ros.sim.rk4`)."""
        self._step(self.params, self.state, tau, self.period, self._work)
        self.steps += 1

    def outputs(self) -> FloatArray:
        """End-effector ``(x, y)`` and, with passive joints, their angles and rates now.

        A view of ``OUTPUTS_SIZE`` floats overwritten by the next call (layout:
        :func:`pdsmc_ros.robots.compiled.outputs`).
        """
        robot_compiled.outputs(self.kind, self.params, self.q, self.qd, self._outputs, self._work)
        return self._outputs

    def warm_up(self) -> None:
        """Load the compiled step now, leaving the state untouched.

        The first call of a kernel in a process loads it from numba's cache
        (tens of ms); a real-time loop calls this before its first tick.
        """
        self._step(self.params, self.state.copy(), np.zeros(self.robot.n), self.period, self._work)
        self.outputs()
