"""The plant under supervision: what the plant node does with effort commands and time (ROS-free).

The plant node decodes messages, publishes and logs; this class decides. In
lockstep the plant steps once per effort command of the current step; in real
time it steps at the control rate with the latest effort. When its controller
is lost (:class:`~pdsmc_ros.sim.safe_mode.Watchdog`) it applies the safe torque
(:func:`~pdsmc_ros.sim.safe_mode.safe_torque`) until a controller answers
again, or ends the run (``on_loss == "end"``). The torque it applies is clamped to the arm's
effort limits (``limit``: a drive saturates; None opts out). After every step it checks the
state (:class:`~pdsmc_ros.sim.divergence.DivergenceCheck`): the first crossing of each joint's
position and velocity limit is a warning; a non-finite or runaway state ends the run with
:attr:`SupervisedPlant.failure` set (nothing more is integrated).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..robots.base import FloatArray
from .divergence import DivergenceCheck
from .plant import PlantStepper
from .safe_mode import SafetyConfig, Watchdog, check_effort, safe_torque

MAX_CATCH_UP = 100  # real time: periods a late tick integrates at most besides its own
# lockstep: the first state goes out again at this period until a controller answers it. A
# subscriber the plant counts as matched may not yet have matched the plant (discovery is
# asymmetric), and with volatile durability it never gets a sample written before then.
FIRST_STATE_RESEND_S = 0.5

Report = Callable[[str, str], None]
"""``report(level, text)`` with level ``"info"``, ``"warn"`` or ``"error"``: a log line and a diagnostic."""


class SupervisedPlant:
    """A :class:`PlantStepper` with effort checks, a watchdog and a safe mode.

    Parameters
    ----------
    stepper : PlantStepper
        The plant.
    last_step : int
        The run's last control step (its effort closes the run).
    watchdog : Watchdog
        When the controller counts as lost.
    safety : SafetyConfig
        What the plant applies meanwhile.
    lockstep : bool
        Lockstep (one step per effort) or real time (one step per period).
    publish_state : callable
        Publishes the current state (the node's encoder).
    report : callable
        :data:`Report`.
    limit : ndarray, optional
        Effort limit of each joint (N m): the applied torque is ``np.clip(tau, -limit, limit)``;
        None: not clamped.
    check : DivergenceCheck, optional
        The state's checks; by default :meth:`DivergenceCheck.for_robot` of the stepper's robot.
    """

    def __init__(self, stepper: PlantStepper, *, last_step: int, watchdog: Watchdog, safety: SafetyConfig,
                 lockstep: bool, publish_state: Callable[[], None], report: Report,
                 limit: FloatArray | None = None, check: DivergenceCheck | None = None) -> None:
        self.stepper = stepper
        self.last_step = last_step
        self.watch = watchdog
        self.safety = safety
        self.lockstep = lockstep
        self.publish_state = publish_state
        self.report = report
        self.n = n = stepper.robot.n
        self.applied = np.zeros(n)  # the torque held over the period that ended at the current state
        self.latest_effort = np.zeros(n)
        self.q_hold = stepper.q.copy()
        self.started = False
        self.first_state_sent_at: float | None = None
        self.done = False
        self.rejected = 0
        self.rejected_reasons: dict[str, int] = {}
        self.limit = limit
        self.check = check or DivergenceCheck.for_robot(stepper.robot)
        self.failure = ""
        """Why the run was stopped (a diverged state), or ``""``."""
        self.inspect()  # the initial state too (a run that starts beyond a limit says so)

    @property
    def step(self) -> int:
        return self.stepper.steps

    @property
    def safe_mode(self) -> str:
        """The safe mode in force, or ``"off"``."""
        return self.safety.mode if self.watch.safe else "off"

    # -- effort ------------------------------------------------------------- #
    def reject(self, reason: str) -> None:
        """Count a refused effort command; report the first few and then every 1000th."""
        self.rejected += 1
        key = reason.split(" (")[0]
        self.rejected_reasons[key] = self.rejected_reasons.get(key, 0) + 1
        if self.rejected <= 5 or self.rejected % 1000 == 0:
            self.report("warn", f"rejected effort command: {reason}; {self.rejected} rejected so far "
                                f"{self.rejected_reasons}")

    def effort(self, step: int, values: object, now: float) -> None:
        """An effort command (``step`` from its ``layout.data_offset``) arrived at ``now``."""
        if self.failure:
            return  # diverged: nothing more is integrated
        tau, reason = check_effort(values, self.n)
        if tau is None:
            self.reject(reason)
            return
        if not self.lockstep:
            self.latest_effort = tau
            if self.watch.effort(now):
                self.resumed()
            return
        if step != self.stepper.steps:
            if self.watch.offer_resume():
                # a controller is back: stop stepping alone and offer it the current state
                self.publish_state()
            self.reject(f"out of order (step {step}, expected {self.stepper.steps})")
            return
        if self.watch.effort(now):
            self.resumed()
        if step >= self.last_step:
            self.done = True  # the controller's effort for t = T closes the run
            return
        self.advance(tau)

    def advance(self, tau: FloatArray) -> None:
        """Integrate one period with ``tau`` held (clamped) and publish the new state."""
        self.integrate(tau)
        self.publish_state()

    def integrate(self, tau: FloatArray) -> None:
        """One period with ``tau`` (clamped to :attr:`limit`) held, then the state's checks."""
        self.applied = tau if self.limit is None else np.clip(tau, -self.limit, self.limit)
        self.stepper.step(self.applied)
        self.inspect()

    def inspect(self) -> None:
        """Check the state now: warn on a joint's first limit crossing; end the run if it diverged."""
        stepper = self.stepper
        hit = self.check.check(stepper.q, stepper.qd, stepper.steps)
        if hit == -1:
            return
        if hit == -2:
            for line in self.check.new_warnings(1.0 / stepper.period):
                self.report("warn", line)
            return
        self.failure = self.check.diverged(hit, stepper.q, stepper.qd, stepper.steps * stepper.period)
        self.report("error", f"the arm {self.failure}; the plant stops (nothing more is integrated)")
        self.done = True

    # -- watchdog and safe mode ---------------------------------------------- #
    def start(self, now: float) -> None:
        """Lockstep: everyone listens; publish the first state."""
        self.started = True
        self.first_state_sent_at = now
        self.publish_state()

    def check_watchdog(self, now: float) -> None:
        """Lockstep: no effort within the watchdog's timeout -> safe mode; in safe mode,
        the arm advances with the safe torque at the watchdog's pace. Until a controller
        has answered, the first state is sent again every ``FIRST_STATE_RESEND_S``."""
        if not self.started or self.done:
            return
        if not self.watch.armed and self.stepper.steps == 0 and self.first_state_sent_at is not None \
                and now - self.first_state_sent_at >= FIRST_STATE_RESEND_S:
            self.first_state_sent_at = now
            self.publish_state()
            return
        if self.watch.lost_in_lockstep(now):
            self.lost(f"no effort for step {self.stepper.steps} within {self.watch.timeout_s:g} s", now)
            return
        for _ in range(self.watch.safe_steps_owed(now)):
            if self.stepper.steps >= self.last_step:
                self.done = True
                return
            self.advance(self.safe_torque())

    def safe_torque(self) -> FloatArray:
        return safe_torque(self.safety, self.stepper.q, self.stepper.qd, self.q_hold)

    def lost(self, why: str, now: float) -> None:
        self.watch.enter(now)
        self.q_hold = self.stepper.q.copy()
        self.report("error", f"controller lost: {why}; safe mode '{self.safety.mode}'")
        if self.safety.on_loss == "end":
            self.report("error", "ending the run (on_controller_loss:=end)")
            self.done = True

    def resumed(self) -> None:
        self.report("info", f"controller back at step {self.stepper.steps}: safe mode off")

    # -- real time ----------------------------------------------------------- #
    def tick(self, late_periods: float, listeners_ready: Callable[[], bool], now: float) -> None:
        """Real time: publish the state, then integrate one period with the latest effort.

        Until the first effort arrives the arm is held at its initial state (the
        controller may still be starting), so the run begins under control. A tick
        more than two periods late integrates the periods it missed too (at most
        ``MAX_CATCH_UP``): the arm's time stays the wall clock's.
        """
        missed = min(int(late_periods), MAX_CATCH_UP) if late_periods > 2.0 else 0
        for _ in range(1 + missed):
            self.publish_state()
            if not self.started:
                # start once everyone listens (the recorder too) and the controller answers
                self.started = self.watch.armed and listeners_ready()
                return
            if self.stepper.steps >= self.last_step:
                self.done = True
                return
            if self.watch.lost_in_period():
                self.lost(f"no effort for {self.watch.periods} periods", now)
                if self.done:
                    return
            self.integrate(self.safe_torque() if self.watch.safe else self.latest_effort)
            if self.failure:
                self.publish_state()  # the diverged state, for the record
            if self.done:
                return
