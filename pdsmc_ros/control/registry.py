"""Control laws by name: what a law is and the registry.

A law module builds a :class:`LawEntry` (its numpy form, and optionally its
compiled form's code and its linear gains for the discrete stability check) and
registers it with :func:`register_law`; its gains live in ``config/gains.yaml``.
A law without a compiled form runs on the numpy path (see :mod:`pdsmc_ros.sim`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..config import choice
from ..errors import InvalidInputError
from ..robots.base import FloatArray, Manipulator

GAIN_NAMES = ("kp", "kd", "ks", "lam", "phi")
"""Diagonal gains a law may use, as rows of :attr:`LawSetup.gains` (``lam`` is the thesis's lambda)."""
KP, KD, KS, LAM, PHI = range(5)

SMC_MODEL_KEYS = ("mass", "coriolis", "gravity", "damping", "motor_inertia", "at_desired")
"""The SMC's model estimate, as entries of :attr:`LawSetup.smc_model` (``config/gains.yaml``)."""
S_MASS, S_CORIOLIS, S_GRAVITY, S_DAMPING, WITH_MOTOR_INERTIA, AT_DESIRED = range(6)


@dataclass(frozen=True)
class LawSetup:
    """What a law is given besides the state and the reference.

    Attributes
    ----------
    gains : ndarray, shape (5, n)
        Rows ``kp, kd, ks, lam, phi`` (:data:`GAIN_NAMES`).
    model : Manipulator
        The nominal robot known to the law (model-based laws).
    smc_model : ndarray, shape (6,)
        The model estimate's scales (:data:`SMC_MODEL_KEYS`).
    """

    gains: FloatArray
    model: Manipulator
    smc_model: FloatArray


NumpyLaw = Callable[[LawSetup, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray], FloatArray]
"""``torque(setup, q, qd, q_ref, qd_ref, qdd_ref)`` for one state (shape ``(n,)``)."""

LinearGains = Callable[[FloatArray, FloatArray, FloatArray], tuple[FloatArray, FloatArray]]
"""``(gains, smc_model, mass) -> (Kp_eff, Kd_eff)``: the law's linear gains inside its boundary layer."""


@dataclass(frozen=True)
class LawEntry:
    """A control law.

    Attributes
    ----------
    name : str
        Its name (``-p type:=``, ``--controller``, ``RunSpec.controller``).
    label : str
        How tables and figures print it.
    gains : tuple of str
        The gains it needs (from :data:`GAIN_NAMES`).
    torque : callable
        The numpy form, :data:`NumpyLaw`.
    equation : str
        Where it is written (thesis equation).
    code : int or None
        The code of its compiled form in :func:`pdsmc_ros.control.laws.compiled_torque`
        (None: numpy only).
    linear_gains : callable or None
        For the discrete stability check (:mod:`pdsmc_ros.control.stability`);
        None: not checked.
    """

    name: str
    label: str
    gains: tuple[str, ...]
    torque: NumpyLaw
    equation: str = ""
    code: int | None = None
    linear_gains: LinearGains | None = None

    def __post_init__(self) -> None:
        unknown = [g for g in self.gains if g not in GAIN_NAMES]
        if not self.name or unknown:
            raise InvalidInputError(f"control law {self.name!r}: needs a name and gains from {GAIN_NAMES}, "
                                    f"got {self.gains}")


LAWS: dict[str, LawEntry] = {}
"""Registered control laws by name, in registration order."""


def register_law(entry: LawEntry) -> LawEntry:
    """Register a control law under its name."""
    if entry.name in LAWS and LAWS[entry.name] is not entry:
        raise InvalidInputError(f"a control law named {entry.name!r} is already registered")
    LAWS[entry.name] = entry
    return entry


def unregister_law(name: str) -> None:
    """Remove a registered law (a test's own law, for example)."""
    LAWS.pop(name, None)


def law_names() -> tuple[str, ...]:
    """Names of the registered laws."""
    return tuple(LAWS)


def law(name: str) -> LawEntry:
    """The registered law ``name`` (a ConfigError listing the others if there is none)."""
    return LAWS[choice(name, law_names(), "controller")]


def law_label(name: str) -> str:
    """How tables print the law ``name``."""
    return law(name).label


def smc_model_vector(smc_model: Mapping[str, float]) -> FloatArray:
    """:attr:`LawSetup.smc_model` from its mapping (every key of :data:`SMC_MODEL_KEYS`)."""
    return np.array([float(smc_model[k]) for k in SMC_MODEL_KEYS])
