"""What the stack does when something goes wrong (ROS-free).

* :func:`check_effort` -- an effort command is applied only if it has one
  finite value per actuated joint and (in lockstep) belongs to the current step.
* :func:`safe_torque` -- the plant's safe mode when no effort arrives in time:
  ``damp`` (no drive torque, only braking ``-D qd``) or ``hold`` (stiff hold of
  the configuration where the controller was lost, ``Kp (q_hold - q) - Kd qd``).
* :func:`limit_torque` -- optional per-joint saturation of the controller output.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InvalidInputError
from .models import FloatArray

SAFE_MODES = ("damp", "hold")
ON_LOSS = ("resume", "end")
# Upper bounds of the safe-mode gains (also the plant parameters' declared ranges): far
# above any useful value, low enough that the safe torque stays finite.
MAX_SAFE_DAMPING = 1.0e6  # N m s/rad
MAX_SAFE_STIFFNESS = 1.0e7  # N m/rad


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


def check_effort(data: object, n: int, step: int | None = None, expected: int | None = None) -> tuple[FloatArray | None, str]:
    """``(torque, "")`` if the command may be applied, else ``(None, reason)``."""
    if type(data) is tuple and len(data) == n and (expected is None or step == expected):
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
    if expected is not None and step != expected:
        return None, f"out of order (step {step}, expected {expected})"
    return tau, ""


def limit_torque(tau: FloatArray, limit: FloatArray | None) -> tuple[FloatArray, bool]:
    """Clamp to ``|tau_i| <= limit_i``; returns the torque and whether it was clamped."""
    if limit is None:
        return tau, False
    clamped = np.clip(tau, -limit, limit)
    return clamped, bool(np.any(clamped != tau))
