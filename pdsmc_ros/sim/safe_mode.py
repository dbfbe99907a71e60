"""The plant's supervision of its controller (ROS-free): safe mode when no effort arrives in time.

* :func:`check_effort` -- an effort command is applied only if it has one
  finite value per actuated joint (the plant checks in lockstep that it is for the current step).
* :class:`Watchdog` -- when the plant enters and leaves safe mode.
* :func:`safe_torque` -- the plant's safe mode: ``damp`` (no drive torque, only braking ``-D qd``)
  or ``hold`` (stiff hold of the configuration where the controller was lost,
  ``Kp (q_hold - q) - Kd qd``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..parameters.tables import MAX_SAFE_DAMPING, MAX_SAFE_STIFFNESS, ON_LOSS, SAFE_MODES
from ..robots.base import FloatArray


@dataclass(frozen=True)
class SafetyConfig:
    """Plant safe-mode settings.

    Attributes
    ----------
    mode : {"damp", "hold"}
        What the plant applies while the controller is lost.
    damping : float
        Braking gain ``D`` (N m s/rad) of both modes.
    stiffness : float
        ``Kp`` (N m/rad) of ``hold``.
    on_loss : {"resume", "end"}
        Resume control when a controller answers again, or end the run.
    """

    mode: str = "damp"
    damping: float = 5.0
    stiffness: float = 200.0
    on_loss: str = "resume"

    def __post_init__(self) -> None:
        if self.mode not in SAFE_MODES:
            raise InvalidInputError(f"safe_mode must be one of {', '.join(SAFE_MODES)}, got {self.mode!r}")
        if self.on_loss not in ON_LOSS:
            raise InvalidInputError(f"on_controller_loss must be one of {', '.join(ON_LOSS)}, got {self.on_loss!r}")
        for name, most in (("damping", MAX_SAFE_DAMPING), ("stiffness", MAX_SAFE_STIFFNESS)):
            value = getattr(self, name)
            if not np.isfinite(value) or not 0.0 <= value <= most:
                raise InvalidInputError(f"safe_{name} must be a finite number in [0, {most:g}], got {value!r}")


def safe_torque(config: SafetyConfig, q: FloatArray, qd: FloatArray, q_hold: FloatArray) -> FloatArray:
    """Torque of the safe mode (see :class:`SafetyConfig`)."""
    tau = -config.damping * qd
    if config.mode == "hold":
        tau = tau + config.stiffness * (q_hold - q)
    return tau


def check_effort(data: object, n: int) -> tuple[FloatArray | None, str]:
    """``(torque, "")`` if the command may be applied, else ``(None, reason)``.

    One finite value per actuated joint; whether it is for the current step is the
    plant's own check (lockstep only).
    """
    if type(data) is tuple and len(data) == n:
        try:  # the loop's path: the decoder's tuple of floats
            if all(map(math.isfinite, data)):
                return np.array(data, dtype=float), ""
        except (TypeError, OverflowError):
            pass  # judged below
    try:
        tau = np.asarray(data, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        return None, "not numeric"
    if tau.shape != (n,):
        return None, f"wrong length {tau.size} (needs {n})"
    if not np.all(np.isfinite(tau)):
        return None, "non-finite value"
    return tau, ""


# --------------------------------------------------------------------------- #


class Watchdog:
    """The plant's supervision of its controller: when to enter and leave safe mode.

    ROS-free state machine; the plant node feeds it times and events and does the
    stepping, logging and diagnostics. Armed once a controller has answered
    (start-up may take seconds). In lockstep a controller is lost when no effort
    was applied for ``timeout_s`` of wall time; the arm then advances with the
    safe torque at ``time_scale`` x wall-clock pace (:meth:`safe_steps_owed`).
    In real time it is lost after ``periods`` control periods without an effort.

    Parameters
    ----------
    rate : float
        Control rate (Hz).
    timeout_s : float
        Lockstep: wall time without an applied effort that loses the controller.
    periods : int
        Real time: control periods without an effort that lose the controller.
    time_scale : float
        Lockstep safe mode: sim time per wall time (1 real time, 0 frozen).
    """

    def __init__(self, *, rate: float, timeout_s: float, periods: int, time_scale: float) -> None:
        self.rate = rate
        self.timeout_s = timeout_s
        self.periods = periods
        self.time_scale = time_scale
        self.armed = False  # a controller has answered
        self.safe = False
        self.awaiting_resume = False  # lockstep: a controller is back, offered the current state
        self.last_progress = 0.0
        self.periods_without_effort = 0
        self._debt = 0.0  # lockstep safe-mode steps owed to the wall clock
        self._since = 0.0

    def effort(self, now: float) -> bool:
        """An effort was applied at ``now``; whether it ends safe mode."""
        self.armed = True
        self.last_progress = now
        self.periods_without_effort = 0
        if not self.safe:
            return False
        self.safe = self.awaiting_resume = False
        return True

    def lost_in_lockstep(self, now: float) -> bool:
        """Lockstep: whether the controller is lost now (it was not before)."""
        return self.armed and not self.safe and now - self.last_progress > self.timeout_s

    def lost_in_period(self) -> bool:
        """Real time: one period passed; whether the controller is lost now (it was not before)."""
        self.periods_without_effort += 1
        return not self.safe and self.periods_without_effort > self.periods

    def enter(self, now: float) -> None:
        """Safe mode from ``now`` on."""
        self.safe = True
        self.awaiting_resume = False
        self._debt = 0.0
        self._since = now

    def offer_resume(self) -> bool:
        """Lockstep: an effort for another step came in safe mode; whether to offer the
        controller the current state (once: the plant stops stepping alone meanwhile)."""
        if not self.safe or self.awaiting_resume:
            return False
        self.awaiting_resume = True
        return True

    def safe_steps_owed(self, now: float) -> int:
        """Lockstep safe mode: steps to take now to keep ``time_scale`` x wall-clock pace.

        After a stall at most 0.1 s of wall time is caught up at once.
        """
        if not self.safe or self.awaiting_resume:
            return 0
        owed = (now - self._since) * self.time_scale * self.rate
        self._since = now
        self._debt = min(self._debt + owed, 0.1 * self.time_scale * self.rate + 1.0)
        steps = int(self._debt)
        self._debt -= steps
        return steps
