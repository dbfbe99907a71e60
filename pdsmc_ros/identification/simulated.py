"""An excitation run in the project's own simulator: what a recorded run would hold, in-process.

The plant (any robot: a "true" arm whose URDF and options differ from the model's) follows an
excitation under a control law with the nominal model, through the same compiled closed loop
as ``pdsmc simulate`` (:func:`pdsmc_ros.sim.loop.run_loop`: RK4 and a zero-order hold at the
control rate, the torque clamped to the effort limits). The joint states and the torques the
plant received are what a driver reports; :func:`write_joint_states` puts them in a bag as the
recorder would (``/joint_states`` with efforts), so ``pdsmc identify`` reads them like any run.

:func:`excite_stand_in` runs it on the MuJoCo stand-in instead, in lockstep and in-process
(:mod:`pdsmc_ros.sim.mujoco_lockstep`), with its nuisances (friction, an unknown payload, the
encoder, a differenced velocity, the command's delay and lag): the joint states are what its
drive publishes, the efforts the torque MuJoCo applied, as the ``mujoco_driver`` node publishes them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..control.law import ControlLaw
from ..control.registry import Gains, smc_model_vector
from ..control.soft_limits import effort_only_table
from ..errors import InvalidInputError
from ..robots.base import FloatArray, Manipulator
from ..sim.loop import run_loop
from ..sim.mujoco_lockstep import StandIn
from .excitation import FourierExcitation

__all__ = ["EXACT_MODEL", "SimulatedRun", "StandInTruth", "excite_stand_in", "simulate_excitation",
           "write_joint_states"]

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


def _law(model: Manipulator, controller: str, gains: dict[str, ArrayLike] | None, rate: float) -> ControlLaw:
    gains = gains or {"omega_n": [30.0] * model.n, "zeta": [1.0] * model.n}
    matrix = Gains.from_mapping(gains, model.n, controller).matrix()
    return ControlLaw(controller, matrix, smc_model_vector(EXACT_MODEL), model, 1.0 / rate)


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
    law = _law(model, controller, gains, rate)
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


@dataclass(frozen=True)
class StandInTruth:
    """What the stand-in's MuJoCo model holds, read back from it: the figures an identification
    of its runs is checked against.

    Attributes
    ----------
    friction_coulomb, friction_viscous, armature : ndarray, shape (n,)
        Each actuated joint's ``frictionloss``, ``damping`` and ``armature`` in MuJoCo's model.
    payload_mass : float
    payload_com : ndarray, shape (3,)
        The unknown load in the tool frame.
    summary : str
        The nuisances, one line (:meth:`~pdsmc_ros.sim.realism.Realism.summary`).
    """

    friction_coulomb: FloatArray
    friction_viscous: FloatArray
    armature: FloatArray
    payload_mass: float
    payload_com: FloatArray
    summary: str


def excite_stand_in(robot: str, plant: Manipulator, model: Manipulator, excitation: FourierExcitation,
                    stand_in: StandIn, *, periods: float, rate: float, start: float = 0.0, controller: str = "ctc",
                    gains: dict[str, ArrayLike] | None = None) -> tuple[SimulatedRun, StandInTruth]:
    """``periods`` periods of ``excitation`` (from ``start`` s into it) on the MuJoCo stand-in of
    ``robot`` (``plant``: its description) with ``stand_in``'s nuisances, at ``rate`` Hz, under
    ``controller`` with ``gains`` (:func:`simulate_excitation`'s default) and ``model`` as its model.

    The run's samples are the ``mujoco_driver`` node's messages: at the end of each tick the state
    its drive publishes (the encoder's count, the differenced velocity) and the torque MuJoCo
    applied over that tick (after the command's delay, its lag and the torque-speed line). Its
    ``reference`` is the excitation at those instants. Also what MuJoCo's model holds (the truth).

    Raises
    ------
    InvalidInputError
        The run diverged, or a nuisance refused (:mod:`pdsmc_ros.sim.realism`).
    """
    law = _law(model, controller, gains, rate)
    loop = stand_in.loop(robot, rate, plant)
    steps = int(round(periods * excitation.period * rate))
    t = np.arange(steps + 1) / rate
    q, qd, qdd = excitation.sample(t + start)
    refs = np.ascontiguousarray(np.stack([q, qd, qdd], axis=1))
    *_, outcome = loop(plant, law, q[0].copy(), refs, 1.0 / rate, 1, effort_only_table(plant.effort_limits, plant.n),
                       drive_record=True)
    if outcome.diverged:
        raise InvalidInputError(f"the excitation run on the stand-in {outcome.diverged}")
    drive = outcome.step_drive
    # the message of tick k: the state published after it (sensed at k + 1) and its torque
    run = SimulatedRun(t[1:], drive[1:, 0], drive[1:, 1], drive[:-1, 2], q[1:])
    arm = loop.arm
    dof = arm.dof[:arm.n]
    truth = StandInTruth(arm.model.dof_frictionloss[dof].copy(), arm.model.dof_damping[dof].copy(),
                         arm.model.dof_armature[dof].copy(), float(loop.realism.payload_mass),
                         np.asarray(loop.realism.payload_com, dtype=float).copy(), loop.realism.summary())
    return run, truth
