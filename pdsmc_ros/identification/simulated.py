"""An excitation run in the project's own simulator: what a recorded run would hold, in-process.

The plant (any robot: a "true" arm whose URDF and options differ from the model's) follows an
excitation under a control law with the nominal model, through the same compiled closed loop
as ``pdsmc simulate`` (:func:`pdsmc_ros.sim.loop.run_loop`: RK4 and a zero-order hold at the
control rate, the torque clamped to the effort limits). The joint states and the torques the
plant received are what a driver reports; :func:`write_joint_states` puts them in a bag as the
recorder would (``/joint_states`` with efforts), so ``pdsmc identify`` reads them like any run.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..control.gains import Gains
from ..control.law import ControlLaw
from ..control.registry import smc_model_vector
from ..control.soft_limits import effort_only_table
from ..errors import InvalidInputError
from ..robots.base import FloatArray, Manipulator
from ..sim.loop import run_loop
from .excitation import FourierExcitation

__all__ = ["EXACT_MODEL", "SimulatedRun", "simulate_excitation", "write_joint_states"]

EXACT_MODEL = {"mass": 1.0, "coriolis": 1.0, "gravity": 1.0, "damping": 1.0, "motor_inertia": 1.0, "at_desired": 0.0}
"""The model-based laws' estimate: the nominal model as it is (no 0.9 / 1.1 scaling)."""


@dataclass(frozen=True)
class SimulatedRun:
    """Times (s), the plant's positions, velocities and the torques it received (``(k, n)``)."""

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    tau: FloatArray
    reference: FloatArray


def simulate_excitation(plant: Manipulator, model: Manipulator, excitation: FourierExcitation, *, periods: float,
                        rate: float = 1000.0, start: float = 0.0, controller: str = "ctc",
                        gains: dict[str, ArrayLike] | None = None) -> SimulatedRun:
    """``periods`` periods of ``excitation`` (from ``start`` s into it) on ``plant``, at ``rate`` Hz,
    under ``controller`` with ``gains`` (by default computed torque with ``omega_n`` 30 rad/s,
    critically damped) and ``model`` as its nominal model.

    Raises
    ------
    InvalidInputError
        The run diverged (the law's gains and the plant do not go together).
    """
    n = plant.n
    gains = gains or {"omega_n": [30.0] * n, "zeta": [1.0] * n}
    matrix = Gains.from_mapping(gains, n, controller).matrix()
    law = ControlLaw(controller, matrix, smc_model_vector(EXACT_MODEL), model, 1.0 / rate)
    steps = int(round(periods * excitation.period * rate))
    t = np.arange(steps + 1) / rate
    q, qd, qdd = excitation.sample(t + start)
    refs = np.ascontiguousarray(np.stack([q, qd, qdd], axis=1))
    out_q, out_qd, out_tau, outcome = run_loop(plant, law, q[0].copy(), refs, 1.0 / rate, 1,
                                               effort_only_table(plant.effort_limits, n), every_step=True)
    if outcome.diverged:
        raise InvalidInputError(f"the simulated excitation run {outcome.diverged}")
    return SimulatedRun(t, out_q, out_qd, out_tau, q)


def write_joint_states(path: str | Path, joint_names: tuple[str, ...], t: FloatArray, q: FloatArray,
                       qd: FloatArray, tau: FloatArray, *, efforts: bool = True) -> None:
    """A bag (a new directory) with ``/joint_states`` stamped ``t`` (``efforts`` False: without the
    effort field, as some drivers publish)."""
    from rosbags.typesys import Stores, get_typestore

    from ..bag.cdr import encode_joint_state
    from ..bag.writer import MessageAppender, open_new_bag

    writer = open_new_bag(str(path))
    try:
        connection = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState",
                                           typestore=get_typestore(Stores.ROS2_JAZZY))
        append = MessageAppender(writer, connection)
        for k in range(len(t)):
            nanoseconds = int(round(t[k] * 1e9))
            sec, nanosec = divmod(nanoseconds, 1_000_000_000)
            append.append(nanoseconds, encode_joint_state(sec, nanosec, joint_names, q[k].tolist(), qd[k].tolist(),
                                                          tau[k].tolist() if efforts else []))
    finally:
        writer.close()
