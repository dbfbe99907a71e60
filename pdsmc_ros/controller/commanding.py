"""What the controller node decides, without ROS: which state meets which reference, and
which torque may go out."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np

from ..bag.stamps import stamp_step
from ..control.soft_limits import SOFT_VELOCITY_BAND, soft_limit
from ..errors import InvalidInputError
from ..parameters.tables import DEFAULT_RUNAWAY_POSITION_MARGIN, DEFAULT_RUNAWAY_VELOCITY_FACTOR, RUNAWAY_STOPS
from ..robots.base import FloatArray
from ..sim.divergence import DivergenceCheck
from .hold import Hold

MAX_STEP = 2**32 - 1  # an effort command's layout.data_offset is a uint32
Reference = tuple[FloatArray, FloatArray, FloatArray]
"""``(q_d, qd_d, qdd_d)`` of one instant."""
Paired = tuple[int, FloatArray, FloatArray, Reference]
"""``(step, q, qd, reference)``: a state and its reference, ready for the law."""


class TrajectorySource(Protocol):
    def begin(self, t: float) -> None: ...  # the loop samples it at t next (the first time: its start)

    def sample(self, t: float) -> Reference: ...


class LockstepPairing:
    """Lockstep: the torque of step ``k`` once the state and the reference of step ``k`` are in.

    References come from the stream (one per step, sent ahead, in step order) or
    from a trajectory goal (sampled at ``step / rate``); whichever spoke last
    drives. References of steps whose state will not come (the plant stepped
    alone in safe mode) are dropped once a later state is paired.

    Parameters
    ----------
    rate : float
        Control rate (Hz).
    last_step : int
        The run's last step; :attr:`finished` once it is paired.
    """

    def __init__(self, rate: float, last_step: int) -> None:
        self.rate = rate
        self.last_step = last_step
        self.state: tuple[int, FloatArray, FloatArray] | None = None  # waiting for its reference
        self.refs: dict[int, Reference] = {}
        self.oldest = 0  # no reference of an earlier step is kept
        self.paired = -1  # the last step paired: a reference at or before it comes too late
        self.trajectory: TrajectorySource | None = None
        self.source: str | None = None  # "reference" or "trajectory"
        self.next_step = 0  # the step a command would be for now
        self.finished = False

    def step_of(self, sec: int, nanosec: int) -> int | None:
        """The control step a sim-time stamp names, or None if it names none."""
        step = stamp_step(sec, nanosec, self.rate)
        return step if 0 <= step <= MAX_STEP else None

    @property
    def stop_step(self) -> int:
        """The step a zero command sent now is for."""
        return min(self.next_step, MAX_STEP)

    def add_state(self, step: int, q: FloatArray, qd: FloatArray) -> Paired | None:
        """The state of ``step``; what :meth:`take` gives now."""
        self.state = (step, q, qd)
        return self.take()

    def add_reference(self, step: int, ref: Reference) -> Paired | None:
        """The reference of ``step``; what :meth:`take` gives now (usually nothing: references
        come ahead of their states)."""
        self.source = "reference"
        if step <= self.paired:
            return None  # a step already paired or skipped
        # the smallest step kept: a reference sent again for a step before the first one received
        # (a reader that matched the trajectory in the middle of its first window gets that
        # window again when the plant offers its first state again) is kept too
        if not self.refs or step < self.oldest:
            self.oldest = step
        self.refs[step] = ref
        state = self.state
        return None if state is None or state[0] != step else self.take()

    def drive(self, trajectory: TrajectorySource) -> None:
        """A trajectory goal drives from now on (until the next streamed reference)."""
        self.trajectory = trajectory
        self.source = "trajectory"

    def take(self) -> Paired | None:
        """``(step, q, qd, reference)`` if the pending state can be computed now."""
        if self.state is None:
            return None
        step, q, qd = self.state
        if self.source == "trajectory" and self.trajectory is not None:
            self.trajectory.begin(step / self.rate)
            ref = self.trajectory.sample(step / self.rate)
            self.refs.pop(step, None)
        else:
            found = self.refs.pop(step, None)
            if found is None:
                return None
            ref = found
        if self.oldest <= step:
            # references of states that will not come (the plant stepped alone): by step, not by
            # iterating the dict, whose scan over the popped entries at its front grows with the
            # lookahead (about 0.4 us a step at 500 references ahead)
            for skipped in range(self.oldest, step):
                self.refs.pop(skipped, None)
            self.oldest = step + 1
        self.paired = step
        self.state = None
        self.next_step = step + 1
        if step >= self.last_step:
            self.finished = True
        return step, q, qd, ref


class TorqueGuard:
    """The last checks before a torque goes out: the arm's soft limits, then never a non-finite value.

    :meth:`limit` applies the output limits (:func:`~pdsmc_ros.control.soft_limits.soft_limit`:
    ros2_control's soft limits of an effort command, robot order) to the law's torque for the
    state it was computed from, and counts the periods it changed (:attr:`clamped`) and, per
    joint, the periods at the effort limit (:attr:`joint_saturated`); :meth:`check` refuses a
    non-finite torque at publication.
    Both say when to log (the first five, then every 1000th).

    Parameters
    ----------
    table : ndarray, shape (6, n), or None
        :func:`~pdsmc_ros.control.soft_limits.soft_limit_table` in robot order; None: no limits
        (``enforce_limits:=false``).
    """

    def __init__(self, table: FloatArray | None) -> None:
        self.table = None if table is None else np.ascontiguousarray(table, dtype=float)
        n = 0 if table is None else self.table.shape[1]  # type: ignore[union-attr]
        self.non_finite = 0
        self.clamped = 0
        self.joint_saturated = np.zeros(max(n, 1), dtype=np.int64)

    def limit(self, tau: FloatArray, q: FloatArray, qd: FloatArray) -> str:
        """Limit ``tau`` (robot order, in place) for the state ``(q, qd)``; a line to log ("" for none)."""
        if self.table is None or not soft_limit(tau, np.asarray(q, dtype=float), np.asarray(qd, dtype=float),
                                                self.table, self.joint_saturated, 1):
            return ""
        self.clamped += 1
        return _every(self.clamped, f"torque limited by the soft limits ({self.clamped} periods so far)")

    def check(self, tau: FloatArray) -> tuple[list[float] | None, str]:
        """The values to publish (None: refused) and a line to log ("" for none)."""
        values = tau.tolist()
        if all(map(math.isfinite, values)):
            return values, ""
        self.non_finite += 1
        return None, _every(self.non_finite, f"non-finite torque {values} not published ({self.non_finite} so far)")


STOP_DAMPING_RATIO = 0.25
"""The ``damp`` stop's gain per joint is at most ``0.25 M_ii(q) / h`` (``M_ii``: the joint's
inertia where the stop begins, ``h``: the control period): a damping torque of a delayed,
sampled loop stays stable only below ``M / h`` times a factor that shrinks with the delay
(0.25 keeps a stop stable with three periods of delay)."""


class RunawayGuard:
    """The controller's runaway stop: a joint beyond ``velocity_factor`` times its velocity limit,
    or beyond a position limit by ``position_margin``, (or a state not finite) stops the motion.

    Once tripped the guard is latched until :meth:`reset` (the lifecycle's activation): the
    active goal is aborted and the output is the stop torque (:meth:`torque`): ``damp``, a
    damping torque ``-D qd`` (``D`` the smaller of ``effort / (0.1 v_max)`` and
    :data:`STOP_DAMPING_RATIO` ``M_ii / h``, clamped to the effort limits) that brings the arm
    to rest, or ``zero``, no torque at all.

    Parameters
    ----------
    names : sequence of str
        Actuated joints, robot order.
    position_limits, velocity_limits, effort_limits : ndarray
        The arm's limits (robot order; infinite where unknown).
    inertia : callable
        ``inertia(q)``: the diagonal of the arm's mass matrix at ``q`` (the damp stop's bound).
    period : float
        The control period ``h`` (s).
    velocity_factor, position_margin : float
        The trip bounds (:data:`DEFAULT_RUNAWAY_VELOCITY_FACTOR`, :data:`DEFAULT_RUNAWAY_POSITION_MARGIN`).
    stop : {"damp", "zero"}
        The output once tripped.
    """

    def __init__(self, names: tuple[str, ...] | list[str], position_limits: FloatArray, velocity_limits: FloatArray,
                 effort_limits: FloatArray, *, inertia: Callable[[FloatArray], FloatArray], period: float,
                 velocity_factor: float = DEFAULT_RUNAWAY_VELOCITY_FACTOR,
                 position_margin: float = DEFAULT_RUNAWAY_POSITION_MARGIN, stop: str = "damp") -> None:
        if stop not in RUNAWAY_STOPS:
            raise InvalidInputError(f"runaway.stop must be one of {', '.join(RUNAWAY_STOPS)}, got {stop!r}")
        self.check = DivergenceCheck(names, position_limits, velocity_limits, velocity_factor=velocity_factor,
                                     position_margin=position_margin)
        self.effort = np.asarray(effort_limits, dtype=float)
        velocity = np.asarray(velocity_limits, dtype=float)
        known = np.isfinite(self.effort) & np.isfinite(velocity) & (velocity > 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            self.most_damping = np.where(known, self.effort / (SOFT_VELOCITY_BAND * np.where(known, velocity, 1.0)),
                                         np.inf)
        self.inertia = inertia
        self.period = period
        self.stop = stop
        self.reason = ""  # why it tripped ("" while it has not)
        self.damping = np.zeros(len(self.effort))
        self.trips = 0

    def trip(self, q: FloatArray, qd: FloatArray, t: float) -> str:
        """Check the state ``(q, qd)`` at time ``t``: the reason, the first time the guard trips
        (it is latched from then on), else ""."""
        if self.reason:
            return ""
        q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)  # a message's tuples, too
        joint = self.check.check(q, qd, 0)
        if joint < 0:
            return ""
        self.reason = self.check.diverged(joint, q, qd, t, what="runaway stop")
        self.trips += 1
        if self.stop == "damp":
            with np.errstate(invalid="ignore"):
                bound = STOP_DAMPING_RATIO * np.asarray(self.inertia(np.nan_to_num(q)), dtype=float) / self.period
            self.damping = np.nan_to_num(np.minimum(self.most_damping, bound), nan=0.0, posinf=0.0)
        return self.reason

    def torque(self, qd: FloatArray) -> FloatArray:
        """The stop torque for the rates ``qd``."""
        if self.stop == "zero":
            return np.zeros(len(self.effort))
        tau = -self.damping * np.nan_to_num(qd)
        return np.clip(tau, -self.effort, self.effort)

    def reset(self) -> None:
        """Unlatch (a new activation)."""
        self.reason = ""


class Staleness:
    """The controller's real-time check that its inputs are fresh (ROS-free).

    Inputs older than ``limit_s`` stop the output; fresh ones resume it.
    """

    def __init__(self, limit_s: float) -> None:
        self.limit_s = limit_s
        self.stale = False

    def update(self, now: float, state_time: float, reference_time: float | None) -> str:
        """``"stale"`` or ``"fresh"`` when the inputs just became so, else ``""``.

        ``reference_time`` is None when the reference is computed locally (always fresh).
        """
        stale = now - state_time > self.limit_s or (
            reference_time is not None and now - reference_time > self.limit_s)
        if stale == self.stale:
            return ""
        self.stale = stale
        return "stale" if stale else "fresh"


def _every(count: int, text: str) -> str:
    return text if count <= 5 or count % 1000 == 0 else ""


class LatestInputs:
    """Real time: the latest state and reference, and whether they are fresh enough to command.

    Whichever source spoke last drives: the reference stream, a trajectory (topic or
    goal), or a hold (:class:`~pdsmc_ros.controller.hold.Hold`). With none yet (after
    :meth:`activate`), the first complete state is held, as joint_trajectory_controller
    holds the position it finds on activation.

    Parameters
    ----------
    stale_s : float
        Inputs older than this stop the output (:class:`Staleness`).
    """

    def __init__(self, stale_s: float) -> None:
        self.staleness = Staleness(stale_s)
        self.state: tuple[FloatArray, FloatArray] | None = None  # None: the latest state was incomplete
        self.last_q: FloatArray | None = None  # the latest complete state's position (where a hold holds)
        self.reference: Reference | None = None
        self.trajectory: TrajectorySource | None = None
        self.source: str | None = None  # "reference" or "trajectory": whichever spoke last
        self.state_time = self.reference_time = 0.0

    def activate(self) -> None:
        """Forget what drove before: hold the first complete state that comes from now on (an
        outage before the deactivation is over: its first state is not "fresh again", which would
        end a goal accepted meanwhile)."""
        self.source, self.trajectory, self.state, self.state_time = None, None, None, 0.0
        self.staleness.stale = False

    def add_state(self, q: FloatArray, qd: FloatArray, now: float) -> None:
        self.state, self.state_time, self.last_q = (q, qd), now, q

    def add_reference(self, ref: Reference, now: float) -> None:
        self.reference, self.reference_time, self.source = ref, now, "reference"

    def drive(self, trajectory: TrajectorySource) -> None:
        # the trajectory first: a tick between the two stores samples the old one once, never None
        self.trajectory = trajectory
        self.source = "trajectory"

    def hold(self, why: str, q: FloatArray | None = None) -> bool:
        """Hold ``q`` (default: the latest complete state's position) from now on (whether there
        is a position to hold)."""
        if q is None:
            q = self.last_q
        if q is None:
            return False
        self.drive(Hold(q, why))
        return True

    def take(self, now: float, clock: Callable[[], float]
             ) -> tuple[tuple[FloatArray, FloatArray, Reference, float] | None, str]:
        """``((q, qd, reference, t) or None, change)``: what to command from now (None: nothing;
        a trajectory is sampled at ``t = clock()``, the time the command is computed), and
        ``"stale"`` / ``"fresh"`` when the inputs just became so."""
        if self.state_time == 0.0:
            return None, ""
        if self.source is None:
            if self.state is None:
                return None, ""
            self.hold("activation")
        from_stream = self.source == "reference"
        change = self.staleness.update(now, self.state_time, self.reference_time if from_stream else None)
        if self.staleness.stale or self.state is None:
            return None, change
        t = clock()
        if from_stream:
            ref = self.reference
        else:
            trajectory = self.trajectory
            trajectory.begin(t)  # type: ignore[union-attr]
            ref = trajectory.sample(t)  # type: ignore[union-attr]
        return (*self.state, ref, t), change  # type: ignore[return-value]
