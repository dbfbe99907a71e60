"""The controller's law against the MuJoCo stand-in, in lockstep and in-process (ROS-free):
``pdsmc simulate``, ``compare`` and ``montecarlo`` with ``--plant mujoco``.

The closed loop of :mod:`.loop` with MuJoCo for the plant and the drive of :mod:`.drive` between
them, compiled as one loop: at every control instant ``t_k`` the drive reads MuJoCo's state as the
``mujoco_driver`` node publishes it (:func:`~.drive.sense`), the law computes its torque from that
reading and the reference (the same compiled call as the controller node's,
:func:`~pdsmc_ros.control.law.law_torque`, with the same soft limits), and the command goes
through the drive's delay line and motors into MuJoCo for one period (:func:`~.drive.apply_tick`:
the ``mujoco_driver`` node's tick). The statistics are the true arm's: the samples hold MuJoCo's
exact state, as the in-process simulator's hold its plant's, and the torque the law commanded.

With ``realism`` ``ideal`` the drive is transparent and MuJoCo's RK4 step at the control period
is the in-process plant's integrator and zero-order hold: a run reproduces the in-process
simulator's (test/sim/test_mujoco_lockstep.py says how closely, per arm). MuJoCo's automatic reset
on a diverging state is off in the loop's model: a run that diverges is stopped and reported as
the in-process simulator's is (:class:`~.divergence.DivergenceCheck`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numba import njit

from ..control.law import ControlLaw, law_torque
from ..control.soft_limits import effort_only_table, soft_limit
from ..errors import InvalidInputError
from ..kernels.options import ALLOCATION_FREE
from ..robots import compiled as robot_compiled
from ..robots.base import FloatArray, Manipulator
from .divergence import DivergenceCheck, watch
from .drive import S_Q, S_QD, Drive, apply_tick, mj_step_function, sense
from .loop import LoopOutcome
from .mujoco_model import MujocoArm, _mujoco, build_stand_in, set_state
from .realism import PRESETS, ArmFacts, Realism


@dataclass(frozen=True)
class StandIn:
    """A run's plant is the MuJoCo stand-in: its nuisances and MuJoCo's steps a period.

    Attributes
    ----------
    preset : str
        ``ideal`` or ``bench`` (:data:`~.realism.PRESETS`).
    given : mapping
        Nuisances given explicitly (replacing the preset's), by name.
    seed : int
        Seed of the nuisances' random draws.
    substeps : int
        MuJoCo steps a control period (1: RK4 at the period, the in-process plant's step).
    """

    preset: str = "ideal"
    given: Mapping[str, Any] = field(default_factory=dict)
    seed: int = 0
    substeps: int = 1

    def __post_init__(self) -> None:
        if self.preset not in PRESETS:
            raise InvalidInputError(f"realism must be one of {', '.join(PRESETS)}, got {self.preset!r}")
        if int(self.substeps) < 1:
            raise InvalidInputError(f"substeps must be >= 1, got {self.substeps!r}")

    def for_run(self, seed: int, index: int) -> StandIn:
        """This stand-in with the seed of run ``index`` of a Monte Carlo seeded ``seed`` (drawn from
        ``SeedSequence([seed, index])``: the runs' noises are independent, each repeats)."""
        drawn = int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1, dtype=np.uint64)[0] >> 1)
        return replace(self, seed=drawn)

    def resolve(self, robot: str, rate: float, source: Manipulator | None = None
                ) -> tuple[MujocoArm, Realism, ArmFacts]:
        """The MuJoCo model, the resolved nuisances of ``robot`` at ``rate`` and what they were sized from."""
        return build_stand_in(robot, rate=rate, substeps=self.substeps, preset=self.preset, given=self.given,
                              seed=self.seed, source=source)

    def loop(self, robot: str, rate: float, plant: Manipulator) -> MujocoLoop:
        """A closed loop of one run against the stand-in of ``plant`` (its description: a drawn
        plant, a payload scenario's load)."""
        return MujocoLoop(robot, rate, self, plant)


@njit(**ALLOCATION_FREE)
def _lockstep(step, model, data, qpos, qvel, qadr, vadr, ctrl, params, dstate, ring, ring_valid, dcount,  # noqa: ANN001, ANN202, PLR0913
              noise, code, gains, smc_model, model_kind, model_p, law_state, q, qd, tau, refs, h, sample_every,
              limit, bounds, first, at, counts, out_q, out_qd, out_tau, step_error, step_tau, step_drive, work,
              start_step, advance_last):
    # :func:`pdsmc_ros.sim.loop._loop`'s steps with MuJoCo for the plant and the drive between them;
    # ``q``, ``qd`` end with the true state the loop ended in (the diverged one if it stopped);
    # ``step_drive[k]`` (if not empty): the position and velocity the drive published at step k and
    # the motors' torque over the tick that follows it (0 while braked)
    n = q.shape[0]
    steps = refs.shape[0] - 1
    every_step = step_error.shape[0] > 0
    drive_record = step_drive.shape[0] > 0
    applied = steps + advance_last
    for k in range(steps + 1):
        for i in range(n):
            q[i] = qpos[qadr[i]]
            qd[i] = qvel[vadr[i]]
        if k % sample_every == 0:
            hit = watch(q, qd, start_step + k, bounds, first, at)
            if hit >= 0:
                counts[n] = start_step + k
                counts[n + 1] = hit
                for i in range(n):
                    at[2, i] = q[i]
                    at[3, i] = qd[i]
                return
        sense(q, qd, params, dstate, dcount, noise[k], h)
        law_torque(code, gains, smc_model, model_kind, model_p, dstate[S_Q], dstate[S_QD], refs[k, 0], refs[k, 1],
                   refs[k, 2], tau, work, n, law_state, h)
        soft_limit(tau, dstate[S_Q], dstate[S_QD], limit, counts, 1 if k < applied else 0)
        if k % sample_every == 0:
            j = k // sample_every
            for i in range(n):
                out_q[j, i] = q[i]
                out_qd[j, i] = qd[i]
                out_tau[j, i] = tau[i]
        if every_step:
            for i in range(n):
                step_error[k, i] = refs[k, 0, i] - q[i]
                step_tau[k, i] = tau[i]
        stepped = False
        if k < applied:
            stepped = apply_tick(step, model, data, qvel, vadr, ctrl, params, dstate, ring, ring_valid, dcount, tau, 1)
        if drive_record:
            for i in range(n):
                step_drive[k, 0, i] = dstate[S_Q, i]
                step_drive[k, 1, i] = dstate[S_QD, i]
                step_drive[k, 2, i] = ctrl[i] if stepped else 0.0
    for i in range(n):
        q[i] = qpos[qadr[i]]
        qd[i] = qvel[vadr[i]]


class MujocoLoop:
    """One run's closed loop against the stand-in, called as :func:`pdsmc_ros.sim.loop.run_loop`
    (a whole run, or its stretches in order: MuJoCo's state and the drive's carry from one to the next).

    Parameters
    ----------
    robot : str
        The registered robot (its name: the thesis arms' MuJoCo model is planar).
    rate : float
        The control rate (Hz): the drive's tick.
    stand_in : StandIn
        The nuisances and MuJoCo's substeps.
    plant : Manipulator
        The simulated robot: MuJoCo is built from its description, the nuisances sized for its limits.
    """

    def __init__(self, robot: str, rate: float, stand_in: StandIn, plant: Manipulator) -> None:
        mujoco = _mujoco()
        self.arm, self.realism, self.facts = stand_in.resolve(robot, rate, plant)
        self.rate = float(rate)
        self.plant = plant
        arm = self.arm
        arm.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)  # the loop's own model
        self.data = arm.data()
        revolute = np.array([arm.model.jnt_type[mujoco.mj_name2id(arm.model, mujoco.mjtObj.mjOBJ_JOINT, j)]
                             == mujoco.mjtJoint.mjJNT_HINGE for j in arm.joint_names], dtype=bool)
        self.drive = Drive(self.realism, 1.0 / self.rate, stand_in.substeps, plant.effort_limits, revolute)
        self.qadr = np.ascontiguousarray(arm.qpos[:arm.n], dtype=np.intp)
        self.vadr = np.ascontiguousarray(arm.dof[:arm.n], dtype=np.intp)
        self.steps_run = 0

    def start(self, q0: FloatArray, qd0: FloatArray | None) -> None:
        """Put MuJoCo at ``q0``, ``qd0`` (the five-bar's passive joints closing its loop there)."""
        arm, d = self.arm, self.data
        set_state(arm, d, q0, qd0)
        if arm.passive_joint_names:
            passive = self.plant.passive_joints(np.asarray(q0, dtype=float),
                                                np.zeros(arm.n) if qd0 is None else np.asarray(qd0, dtype=float))
            d.qpos[arm.qpos[arm.n:]] = passive[0]
            d.qvel[arm.dof[arm.n:]] = passive[1]
        _mujoco().mj_forward(arm.model, d)

    def __call__(self, plant: Manipulator, law: ControlLaw, q0: FloatArray, refs: FloatArray, h: float,
                 sample_every: int, torque_limit: FloatArray | None = None, check: DivergenceCheck | None = None, *,
                 qd0: FloatArray | None = None, start_step: int = 0, advance_last: bool = False,
                 every_step: bool = False, drive_record: bool = False
                 ) -> tuple[FloatArray, FloatArray, FloatArray, LoopOutcome]:
        """:func:`~pdsmc_ros.sim.loop.run_loop`'s call and results; ``q0``, ``qd0`` start the run
        (``start_step`` 0), a later stretch goes on from MuJoCo's state. ``drive_record``: the
        outcome's ``step_drive`` holds, at every control instant, what the drive published (position,
        velocity) and the motors' torque over the tick after it (what the ``mujoco_driver`` node
        publishes as the effort of the next state: the torque MuJoCo applied, after the delay, the
        lag and the torque-speed line)."""
        n = plant.n
        if n != self.arm.n:
            raise InvalidInputError(f"the stand-in has {self.arm.n} actuated joints; the plant {n}")
        if abs(h * self.rate - 1.0) > 1e-9:
            raise InvalidInputError(f"the loop's period {h!r} s is not the stand-in's tick (1 / {self.rate:g} Hz)")
        if start_step == 0:
            self.start(np.asarray(q0, dtype=float), qd0)
        rows = refs.shape[0]
        count = (rows - 1) // sample_every + 1
        out_q, out_qd, out_tau = np.empty((count, n)), np.empty((count, n)), np.empty((count, n))
        limit = effort_only_table(None, n) if torque_limit is None else np.ascontiguousarray(torque_limit, dtype=float)
        check = check or DivergenceCheck.for_robot(plant)
        counts = np.zeros(n + 2, dtype=np.int64)
        counts[n] = -1
        step_error = np.empty((rows if every_step else 0, n))
        step_tau = np.empty((rows if every_step else 0, n))
        step_drive = np.empty((rows if drive_record else 0, 3, n))
        end_q, end_qd = np.zeros(n), np.zeros(n)
        drive, d = self.drive, self.data
        _lockstep(mj_step_function(), self.arm.model._address, d._address, d.qpos, d.qvel, self.qadr, self.vadr,
                  d.ctrl, drive.params, drive.state, drive.ring, drive.ring_valid, drive.counters, drive.noise(rows),
                  law.code, law.gains, law.smc_model, law.model_kind, law.model_params, law.state, end_q, end_qd,
                  np.empty(n), np.ascontiguousarray(refs, dtype=float), float(h), int(sample_every), limit,
                  check.bounds, check.first, check.at, counts, out_q, out_qd, out_tau, step_error, step_tau,
                  step_drive, robot_compiled.workspace(n), int(start_step), int(advance_last))
        self.steps_run += rows
        outcome = LoopOutcome(counts[:n].tolist(), warnings=check.new_warnings(1.0 / h), end_q=end_q, end_qd=end_qd,
                              step_error=step_error, step_tau=step_tau, step_drive=step_drive)
        if counts[n] >= 0:
            stop = int(counts[n])
            first_missing = -(-(stop - start_step) // sample_every)
            for out in (out_q, out_qd, out_tau):
                out[first_missing:] = np.nan
            for out in (step_error, step_tau, step_drive):
                out[stop - start_step:] = np.nan
            outcome.diverged_step = stop
            joint = int(counts[n + 1])
            outcome.diverged = check.diverged(joint, check.at[2], check.at[3], stop * h)
        return out_q, out_qd, out_tau, outcome
