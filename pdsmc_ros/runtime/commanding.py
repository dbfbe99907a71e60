"""What the controller node decides, without ROS: which state meets which reference, and
which torque may go out."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Protocol

import numpy as np

from ..bag.stamps import stamp_step
from ..control.safety import Staleness, limit_torque
from ..robots.base import FloatArray
from .hold import Hold

MAX_STEP = 2**32 - 1  # an effort command's layout.data_offset is a uint32
Reference = tuple[FloatArray, FloatArray, FloatArray]
"""``(q_d, qd_d, qdd_d)`` of one instant."""
Paired = tuple[int, FloatArray, FloatArray, Reference]
"""``(step, q, qd, reference)``: a state and its reference, ready for the law."""


class TrajectorySource(Protocol):
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
    """The last check before a torque goes out: never a non-finite one; clamped to the limits if set.

    Counts both; :meth:`check` says when to log (the first five, then every 1000th).
    """

    def __init__(self, limit: FloatArray | None) -> None:
        self.limit = limit
        self.non_finite = 0
        self.clamped = 0

    def check(self, tau: FloatArray) -> tuple[list[float] | None, str]:
        """The values to publish (None: refused) and a line to log ("" for none)."""
        values = tau.tolist()
        if not all(map(math.isfinite, values)):
            self.non_finite += 1
            note = _every(self.non_finite, f"non-finite torque {values} not published ({self.non_finite} so far)")
            return None, note
        if self.limit is None:
            return values, ""
        limited, clamped = limit_torque(np.asarray(tau), self.limit)
        if not clamped:
            return values, ""
        self.clamped += 1
        return limited.tolist(), _every(self.clamped, f"torque limited ({self.clamped} so far)")


def _every(count: int, text: str) -> str:
    return text if count <= 5 or count % 1000 == 0 else ""


class LatestInputs:
    """Real time: the latest state and reference, and whether they are fresh enough to command.

    Whichever source spoke last drives: the reference stream, a trajectory (topic or
    goal), or a hold (:class:`~pdsmc_ros.runtime.hold.Hold`). With none yet (after
    :meth:`activate`), the first complete state is held, as joint_trajectory_controller
    holds the position it finds on activation.

    Parameters
    ----------
    stale_s : float
        Inputs older than this stop the output (:class:`~pdsmc_ros.control.safety.Staleness`).
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
        """Forget what drove before: hold the first complete state that comes from now on."""
        self.source, self.trajectory, self.state, self.state_time = None, None, None, 0.0

    def add_state(self, q: FloatArray, qd: FloatArray, now: float) -> None:
        self.state, self.state_time, self.last_q = (q, qd), now, q

    def add_reference(self, ref: Reference, now: float) -> None:
        self.reference, self.reference_time, self.source = ref, now, "reference"

    def drive(self, trajectory: TrajectorySource) -> None:
        # the trajectory first: a tick between the two stores samples the old one once, never None
        self.trajectory = trajectory
        self.source = "trajectory"

    def hold(self, why: str) -> bool:
        """Hold the latest complete state's position from now on (whether there is one)."""
        if self.last_q is None:
            return False
        self.drive(Hold(self.last_q, why))
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
        ref = self.reference if from_stream else self.trajectory.sample(t)  # type: ignore[union-attr]
        return (*self.state, ref, t), change  # type: ignore[return-value]


class TickTiming:
    """Real time: each tick's ``[wall time, achieved period, compute time, lateness, missed so far]``."""

    FIELDS = 5

    def __init__(self, period: float) -> None:
        self.period = period
        self.missed = 0
        self.last: float | None = None  # the start of the latest tick
        self.achieved = 0.0  # the latest tick's start minus the one before (0 for the first)

    def start(self, lateness: float) -> float:
        """A tick starts ``lateness`` s after its deadline; its start time (``perf_counter``)."""
        self.missed += lateness > self.period
        now = time.perf_counter()
        self.achieved = 0.0 if self.last is None else now - self.last
        self.last = now
        return now

    def row(self, start: float, lateness: float) -> list[float]:
        """The row of a tick that commanded, at its end."""
        return [time.time(), self.achieved, time.perf_counter() - start, lateness, float(self.missed)]
