"""What stands between the physics and the wire on a real arm: the stand-in's nuisances, their
presets and the rules that size them for an arm (ROS-free).

A real arm is not the model a controller is given. Its joints have dry and viscous friction,
its drive publishes the position an encoder counts and a velocity it differentiates and
filters, a command reaches the motors some cycles after the state it was computed from and
the motor's torque follows it with the lag of its current loop, the motor's torque falls with
speed, and the tool the arm carries is not in the model. Each of these is one *nuisance* here,
declared once in the parameter table (:data:`pdsmc_ros.parameters.tables.REALISM`: name, type,
bounds, what it is): the ``mujoco_driver`` node declares them, the ``--plant mujoco`` runs' flags
are made from them (:mod:`pdsmc_ros.cli.stand_in`), and :func:`resolve_realism` checks every value
with them (the same one-line refusal everywhere).

A run's nuisances are resolved in one place, :func:`resolve_realism`: the named preset
(``realism``, :data:`PRESETS`) gives every value, each nuisance given explicitly replaces the
preset's, and the result (:class:`Realism`) holds one value per joint where a nuisance is per
joint. ``ideal`` (the default) is the stand-in as it was before the nuisances: every one off.
``bench`` is an arm like the one on the bench, values typical of a six-axis collaborative arm
(:func:`bench_values`, with the sources of each value and the rule that sizes it for the arm).

Where each nuisance acts:

* ``friction_coulomb`` and ``friction_viscous`` are physics: MuJoCo's joint ``frictionloss`` (stiff
  enough to act as Coulomb friction) and joint damping added to the URDF's
  (:func:`pdsmc_ros.sim.mujoco_model.set_friction`);
* ``payload_mass`` and ``payload_com`` are physics too: a fixed link under the arm's tool frame
  in the description MuJoCo is given, which the controller's model does not have;
* the others are the drive's, between the physics and the wire (:mod:`pdsmc_ros.sim.drive`):
  ``encoder_counts``, ``position_noise``, ``velocity_source`` and ``velocity_filter_hz`` on what
  is published; ``command_delay``, ``torque_bandwidth_hz``, ``torque_speed`` and
  ``no_load_speed`` on what a command does.

Everything drawn at random (the position noise) comes from ``numpy.random.default_rng(seed)``,
so a run repeats exactly.
"""

from __future__ import annotations

import array
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InvalidInputError
from ..parameters.tables import REALISM, REALISM_PRESETS
from ..robots.base import FloatArray

PRESETS = REALISM_PRESETS
"""Named presets of the nuisances (``realism:=``, ``--realism``)."""
BY_NAME = {spec.name: spec for spec in REALISM}
"""The declarations (:data:`pdsmc_ros.parameters.tables.REALISM`), by name."""
SETTINGS = ("realism", "seed")
"""The declarations that are not nuisances themselves: the preset and the seed."""
NUISANCES = tuple(name for name in BY_NAME if name not in SETTINGS)
"""Every nuisance's name, in the table's order."""
SIZES = {"payload_com": 3}
"""Arrays of a fixed size (not one value per joint)."""


class RealismError(InvalidInputError):
    """A nuisance's value is refused: one line naming the parameter and what it allows."""


@dataclass(frozen=True)
class ArmFacts:
    """What sizing the nuisances for an arm needs to know of it.

    Attributes
    ----------
    joint_names : tuple of str
        Actuated joints in the robot's order.
    effort_limits, velocity_limits : ndarray, shape (n,)
        Each joint's limits (the arm's: the ones its controller clamps to; ``inf``: none).
    revolute : ndarray of bool, shape (n,)
        Whether each joint turns (else it slides: an encoder's counts are per metre).
    moving_mass : float
        Mass of the arm's moving links (kg), the base excluded.
    rate : float
        The driver's tick rate (Hz): the period a delay counts and a velocity is differenced over.
    """

    joint_names: tuple[str, ...]
    effort_limits: FloatArray
    velocity_limits: FloatArray
    revolute: np.ndarray
    moving_mass: float
    rate: float

    @property
    def n(self) -> int:
        return len(self.joint_names)


@dataclass(frozen=True)
class Realism:
    """The nuisances of one run, resolved for its arm (:func:`resolve_realism`): one value per
    actuated joint where a nuisance is per joint; 0 (or ``exact``, ``False``) where it is off.

    ``sources`` says where each value came from: ``preset`` (``realism``'s) or ``given``.
    """

    preset: str
    seed: int
    friction_coulomb: FloatArray
    friction_viscous: FloatArray
    encoder_counts: np.ndarray
    position_noise: FloatArray
    velocity_source: str
    velocity_filter_hz: FloatArray
    command_delay: int
    torque_bandwidth_hz: FloatArray
    torque_speed: bool
    no_load_speed: FloatArray
    payload_mass: float
    payload_com: FloatArray
    sources: Mapping[str, str] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.friction_coulomb)

    @property
    def has_physics(self) -> bool:
        """Whether MuJoCo's model itself changes (friction, a payload)."""
        return bool(np.any(self.friction_coulomb > 0) or np.any(self.friction_viscous > 0)
                    or self.payload_mass > 0)

    @property
    def has_drive(self) -> bool:
        """Whether anything stands between the physics and the wire (the drive's nuisances)."""
        return bool(np.any(self.encoder_counts > 0) or np.any(self.position_noise > 0)
                    or self.velocity_source != "exact" or self.command_delay > 0
                    or np.any(self.torque_bandwidth_hz > 0) or self.torque_speed)

    @property
    def is_ideal(self) -> bool:
        """Every nuisance off: the stand-in as a perfect arm (the same steps as before there were any)."""
        return not (self.has_physics or self.has_drive)

    def loop_terms(self) -> tuple[int, FloatArray | None, FloatArray]:
        """What the stability check models of these nuisances (:func:`pdsmc_ros.control.stability.check_gains`):
        the command's delay (ticks), the velocity filter's cut-offs (Hz per joint) when the velocity
        is differenced, else None (the exact velocity), and the viscous friction (N m s/rad per joint,
        which the check adds to the description's damping: linear damping the arm has). The Coulomb
        friction, the torque's lag and the others are not modelled."""
        filtered = self.velocity_filter_hz if self.velocity_source == "difference" else None
        return int(self.command_delay), filtered, self.friction_viscous

    def value(self, name: str) -> Any:
        """A nuisance's value as plain data (lists for arrays)."""
        value = getattr(self, name)
        return value.tolist() if isinstance(value, np.ndarray) else value

    def describe(self) -> dict[str, Any]:
        """Plain data: every nuisance's value and where it came from (logs, bags, reports)."""
        out: dict[str, Any] = {"realism": self.preset, "seed": self.seed}
        out.update({name: self.value(name) for name in NUISANCES})
        out["sources"] = dict(self.sources)
        return out

    def summary(self) -> str:
        """One line naming what is on (``ideal: every nuisance off``)."""
        if self.is_ideal:
            return f"{self.preset}: every nuisance off"
        parts = []
        for name in NUISANCES:
            if name == "payload_com":
                continue
            value = getattr(self, name)
            if name == "velocity_source":
                if value != "exact":
                    parts.append(f"velocity {value}")
                continue
            if name == "torque_speed":
                if value:
                    parts.append("torque-speed line")
                continue
            if name == "no_load_speed" and not self.torque_speed:
                continue
            if np.any(np.asarray(value) > 0):
                values = np.atleast_1d(value)
                shown = f"{values[0]:g}" if np.all(values == values[0]) else ", ".join(f"{v:g}" for v in values)
                parts.append(f"{name} [{shown}]" if BY_NAME[name].per_joint else f"{name} {shown}")
        if self.payload_mass > 0:
            parts[-1] += " at [" + ", ".join(f"{v:g}" for v in self.payload_com) + "] m"
        return f"{self.preset} (seed {self.seed}): " + "; ".join(parts)


# --------------------------------------------------------------------------- #
# The bench preset: a six-axis collaborative arm, and how it is sized for another arm
# --------------------------------------------------------------------------- #
COULOMB_SHARE = 0.04
"""Coulomb friction as a share of each joint's effort limit. A UR10e identified by Mamedov et
al. (Innopolis University, github.com/shamilmamedov/dynamic_calibration, ``UR10E_parameters``:
``fv qd + fc sign(qd) + f0`` per joint) has fc = 12.55, 13.27, 4.99, 2.00, 2.69, 2.30 N m on joints
with effort limits 330, 330, 150, 56, 56, 56 N m: 3.3 to 4.8 %, 3.9 % on average. The Franka
Emika Panda identified by Gaz et al. (IEEE RA-L 2019, their ``get_FrictionTorque.m``) has 0.6 to
1.5 % on its 87 N m joints and 2.5 to 7.0 % on its 12 N m joints."""
VISCOUS_SHARE = 0.06
"""Viscous friction per unit effort limit (N m s/rad per N m = s/rad). The same UR10e: fv = 21.3,
20.2, 10.4, 3.58, 2.49, 3.03 N m s/rad, 0.044 to 0.069 s/rad of its effort limits, 0.060 on average."""
ENCODER_COUNTS = 2**18
"""Counts a revolution: an 18-bit absolute encoder on the joint's output, as the dual-encoder
harmonic joint modules of collaborative arms carry (2^17 to 2^20 counts a turn on such arms)."""
NOISE_COUNTS = 0.5
"""Position noise before the quantisation, in counts (standard deviation): the last count flickers
near its edges, as an absolute encoder's reading does. An assumption, not a data-sheet value."""
VELOCITY_FILTER_HZ = 100.0
"""The differenced velocity's first-order low-pass cut-off: libfranka's default
(``franka::kDefaultCutoffFrequency``, 100 Hz, its ``lowpassFilter`` at 1 kHz)."""
COMMAND_DELAY_S = 0.002
"""Seconds between a command's arrival and the torque it sets: ros2_control reads the state,
updates the controller and writes its command once a cycle, and the drive applies what it was
written at its next cycle; with the bus's own cycle that is about two periods of a 1 kHz loop
(the issue's "a delay of two ticks"; mjlab's ``DelayedActuator`` and PACE model delays of a few
physics steps, PACE identifies one per robot)."""
TORQUE_BANDWIDTH_HZ = 100.0
"""The torque's first-order bandwidth: a harmonic-drive joint with a torque sensor and a PD torque
loop reaches "over 100 Hz" (IEEE Robotics & Automation Magazine, Dec. 2019, p. 50, a time constant of
1.5 ms); a quasi-direct-drive actuator 66 Hz at 6 N m (Perez-Diaz et al., PULSE115-60, 2024)."""
NO_LOAD_FACTOR = 2.0
"""``no_load_speed`` as a multiple of the joint's URDF velocity limit: the arm reaches its rated
speed with half its peak torque left. An assumption: the arms' data sheets give the joint's speed
limit, not the motor's no-load speed."""
TOOL_SHARE = 0.925 / 16.99
"""The unknown tool's mass as a share of the arm's moving mass: a Robotiq 2F-85 gripper (0.925 kg,
its instruction manual's specifications) on a UR5, whose moving links weigh 16.99 kg in its URDF
(example-robot-data's ``ur5_robot.urdf``): 5.4 %."""
TOOL_COM_Z = 0.06
"""m along the tool's z axis: about the middle of a 2F-85's body, an estimate. Scaled with the
cube root of the tool's mass (a geometrically similar tool) on other arms."""
TOOL_MASS = 0.925


def bench_values(facts: ArmFacts) -> dict[str, Any]:
    """The ``bench`` preset sized for an arm (every value's source: the constants above).

    The rule: friction scales with each joint's effort limit (:data:`COULOMB_SHARE`,
    :data:`VISCOUS_SHARE`); the no-load speed with its velocity limit (:data:`NO_LOAD_FACTOR`);
    the tool with the arm's moving mass (:data:`TOOL_SHARE`, its centre of mass with the cube
    root of its mass); the delay is a time (:data:`COMMAND_DELAY_S`), counted in the driver's
    ticks; the encoder, the noise in counts, the filter and the torque bandwidth are the drive
    electronics' and do not change with the arm. A joint without a finite effort limit gets no
    friction (there is nothing to scale); one without a velocity limit no torque-speed line.
    """
    effort = np.where(np.isfinite(facts.effort_limits), facts.effort_limits, 0.0)
    velocity = np.where(np.isfinite(facts.velocity_limits), facts.velocity_limits, np.inf)
    step = _encoder_step(np.full(facts.n, ENCODER_COUNTS), facts.revolute)
    mass = TOOL_SHARE * facts.moving_mass
    return {
        "friction_coulomb": COULOMB_SHARE * effort,
        "friction_viscous": VISCOUS_SHARE * effort,
        "encoder_counts": np.full(facts.n, ENCODER_COUNTS, dtype=np.int64),
        "position_noise": NOISE_COUNTS * step,
        "velocity_source": "difference",
        "velocity_filter_hz": np.full(facts.n, VELOCITY_FILTER_HZ),
        "command_delay": int(round(COMMAND_DELAY_S * facts.rate)),
        "torque_bandwidth_hz": np.full(facts.n, TORQUE_BANDWIDTH_HZ),
        "torque_speed": True,
        "no_load_speed": NO_LOAD_FACTOR * velocity,
        "payload_mass": mass,
        "payload_com": np.array([0.0, 0.0, TOOL_COM_Z * (mass / TOOL_MASS) ** (1.0 / 3.0)]),
    }


def ideal_values(facts: ArmFacts) -> dict[str, Any]:
    """The ``ideal`` preset: every nuisance off (the no-load speed, unused, at twice each velocity limit)."""
    n = facts.n
    velocity = np.where(np.isfinite(facts.velocity_limits), facts.velocity_limits, np.inf)
    return {
        "friction_coulomb": np.zeros(n), "friction_viscous": np.zeros(n),
        "encoder_counts": np.zeros(n, dtype=np.int64), "position_noise": np.zeros(n),
        "velocity_source": "exact", "velocity_filter_hz": np.zeros(n), "command_delay": 0,
        "torque_bandwidth_hz": np.zeros(n), "torque_speed": False, "no_load_speed": NO_LOAD_FACTOR * velocity,
        "payload_mass": 0.0, "payload_com": np.zeros(3),
    }


def _encoder_step(counts: np.ndarray, revolute: np.ndarray) -> FloatArray:
    """The grid of each encoder (rad, or m for a prismatic joint); 0 where there is none."""
    counts = np.asarray(counts, dtype=float)
    span = np.where(revolute, 2.0 * math.pi, 1.0)
    return np.where(counts > 0, span / np.where(counts > 0, counts, 1.0), 0.0)


# --------------------------------------------------------------------------- #
# Checks and resolution
# --------------------------------------------------------------------------- #
def check_value(name: str, value: Any, n: int) -> Any:
    """One nuisance's value, checked by its declaration in the table (the node's start-up and on-set
    checks: the same one-line refusal) and brought to its type: an array of ``n`` for a per-joint
    one (one value standing for every joint).

    Raises
    ------
    RealismError
        One line naming the parameter and what it allows: of another type, out of bounds, NaN,
        a list of the wrong length, an unknown name.
    """
    if name not in BY_NAME:
        raise RealismError(f"unknown nuisance {name!r}; known: {', '.join(BY_NAME)}")
    spec = BY_NAME[name]
    if isinstance(value, np.ndarray | array.array | tuple):
        value = value.tolist() if isinstance(value, np.ndarray) else list(value)
    elif isinstance(value, np.generic):
        value = value.item()
    try:
        value = spec.coerce(value)
    except InvalidInputError as exc:
        raise RealismError(str(exc)) from None
    reason = spec.problem(value, n if spec.per_joint else None)
    if reason:
        raise RealismError(reason)
    if name in SIZES and len(value) != SIZES[name]:
        raise RealismError(f"parameter {name} needs {SIZES[name]} values, got {len(value)}")
    if spec.is_array:
        values = value * n if spec.per_joint and len(value) == 1 else value
        return np.array(values, dtype=np.int64 if spec.element == "int" else float)
    return value


def resolve_realism(facts: ArmFacts, preset: str = "ideal", given: Mapping[str, Any] | None = None, *,
                    seed: int = 0) -> Realism:
    """A run's nuisances: the preset's values, each one in ``given`` replacing its (None: not given).

    Parameters
    ----------
    facts : ArmFacts
        The arm and the driver's rate.
    preset : str
        One of :data:`PRESETS`.
    given : mapping, optional
        Nuisances given explicitly, by name (a node's parameters, a command's flags).
    seed : int
        Seed of the random draws (>= 0).

    Raises
    ------
    RealismError
        One line naming the parameter: a value its declaration refuses; ``torque_speed`` on a joint
        without a finite effort limit.
    """
    preset = check_value("realism", preset, facts.n)
    seed = check_value("seed", seed, facts.n)
    values = (bench_values if preset == "bench" else ideal_values)(facts)
    sources = dict.fromkeys(values, "preset")
    for name, value in (given or {}).items():
        if name in SETTINGS:
            raise RealismError(f"{name} is not a nuisance: give it as preset= or seed=")
        if value is None:
            continue
        values[name] = check_value(name, value, facts.n)
        sources[name] = "given"
    if values["torque_speed"]:
        bad = [j for j, e in zip(facts.joint_names, facts.effort_limits, strict=True) if not np.isfinite(e)]
        if bad:
            raise RealismError(f"parameter torque_speed needs each joint's effort limit; joint {bad[0]!r} has none")
        bad = [j for j, v in zip(facts.joint_names, values["no_load_speed"], strict=True) if not np.isfinite(v)]
        if bad:
            raise RealismError(f"parameter no_load_speed: joint {bad[0]!r} has no velocity limit to derive it "
                               "from; give no_load_speed")
    return Realism(preset=preset, seed=seed, sources=sources, **values)
