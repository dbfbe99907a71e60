"""YAML presets (``config/``) and the description of one run.

A :class:`RunSpec` names everything a run needs -- robot, contour, controller,
gains, scenario, rates -- as plain data, so the same description drives the
in-process simulator, the ROS nodes (as parameters) and the bag metadata.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from . import __version__
from .errors import ConfigError
from .models import Manipulator, RobotParams, make_robot
from .resources import config_dir
from .trajectories import Contour, EllipseContour, JointReference, SegmentContour

ROBOT_NAMES = ("serial_3r", "parallel_5r")
CONTROLLER_NAMES = ("pd", "smc", "pdsmc")
CONTROLLER_LABELS = {"pd": "PD", "smc": "SMC", "pdsmc": "PD-SMC"}
GAIN_NAMES = ("kp", "kd", "ks", "lam", "phi")
REQUIRED_GAINS = {"pd": ("kp", "kd"), "smc": ("ks", "lam", "phi"), "pdsmc": GAIN_NAMES}

DEFAULT_CONTROL_RATE = {"serial_3r": 10000.0, "parallel_5r": 5000.0}
"""Control rates (Hz) that reproduce the continuous-time thesis (NOTES.md section 1).

Measured on the nominal thesis runs, relative change of the mean errors from these rates
to 40 kHz: serial PD and PD-SMC, contour mean 1.2e-5 to 7.2e-5 (circle PD-SMC 1.24e-5,
1.32e-5 on joint 3's mean error); five-bar PD and PD-SMC, contour mean 2e-6 to 1.7e-5,
axial means up to 2.3e-5; the SMC runs, whose switching term reacts to the hold, up to
2.9e-4 (serial) and 5.6e-4 (five-bar). Against the continuous-time limit (Radau, rtol
1e-10) the serial circle PD-SMC run at 10 kHz deviates by about 1e-5 on the axial means
and 1.6e-5 on the contour mean (docs/REPRODUCTION.md, "Discrete loop against the
continuous-time limit"): all far below the deviations from the thesis's tables."""

MAX_CONTROL_STEPS = 10_000_000
"""Control steps one run may hold: the sampled reference and its temporaries take about
400 bytes a step (4 GB here), 200 times the thesis's 50,001-step serial runs."""

SAMPLE_RATE = {"serial_3r": 500.0, "parallel_5r": 5000.0}
"""Rates (Hz) at which the thesis sampled errors for its statistics (Section 4.2)."""

SMC_MODEL_KEYS = ("mass", "coriolis", "gravity", "damping", "motor_inertia", "at_desired")
SMC_MODEL_DEFAULT = {
    "mass": 0.9,
    "coriolis": 0.9,
    "gravity": 1.1,
    "damping": 0.0,
    "motor_inertia": 1.0,
    "at_desired": 0.0,
}
"""The SMC's model estimate of Sections 4.3/4.4: 0.9 Mbar (motor inertia included),
0.9 C, 1.1 G of the nominal robot at the measured state, no damping term."""

PAYLOAD_READINGS = {
    "tip": "a point mass at the end-effector; the SMC's model estimate stays the nominal robot's",
    "link_com": "the load added to the mass of the link that carries the end-effector (serial "
    "link 3, five-bar link 3), at that link's centre of mass with its inertia unchanged; the "
    "SMC's model estimate is rebuilt with it",
}
"""Readings of Section 4.5.2's "a simulated load of 1.5 kg was added at the end-effector"
(``--payload-reading``); ``tip`` is the physical one and the default."""

PAYLOAD_LINK = {"serial_3r": 2, "parallel_5r": 2}
"""Index (from 0) of the link carrying the end-effector: the serial arm's last link, the
five-bar's left distal link, which carries the tip point mass in :class:`models.Parallel5R`."""

CONTOUR_BOUND = {"serial_3r": 2.0e-4, "parallel_5r": 1.5e-4}
"""Contour error bounds (m) of the "% within bound" statistic."""


@functools.lru_cache(maxsize=16)
def _load_yaml(path: str) -> Any:
    try:
        with open(path, encoding="utf-8") as handle:
            return yaml.safe_load(handle)
    except OSError as exc:
        raise ConfigError(f"cannot read {path}: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path} is not valid YAML: {exc}") from exc


def load_config(name: str, directory: Path | None = None) -> Any:
    """Parsed ``config/<name>.yaml``."""
    return _load_yaml(str((directory or config_dir()) / f"{name}.yaml"))


def choice(value: str, allowed: tuple[str, ...] | list[str], what: str) -> str:
    """``value`` if it is one of ``allowed``; a ConfigError listing them otherwise."""
    if value not in allowed:
        raise ConfigError(f"unknown {what} {value!r}; choose one of: {', '.join(allowed)}")
    return value


# --------------------------------------------------------------------------- #
# Gains
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class Gains:
    """Diagonal control parameters per actuated joint (unused ones zero, phi one)."""

    kp: tuple[float, ...]
    kd: tuple[float, ...]
    ks: tuple[float, ...]
    lam: tuple[float, ...]
    phi: tuple[float, ...]

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], n: int, controller: str) -> Gains:
        """Build from a ``{kp: [...], ...}`` mapping, validating names, lengths and signs."""
        unknown = set(data) - set(GAIN_NAMES)
        if unknown:
            raise ConfigError(
                f"unknown gain(s) {sorted(unknown)} for {controller}; allowed: {', '.join(GAIN_NAMES)}"
            )
        missing = [g for g in REQUIRED_GAINS[controller] if g not in data]
        if missing:
            raise ConfigError(f"{controller} needs gains {', '.join(missing)}")
        values: dict[str, tuple[float, ...]] = {}
        for name in GAIN_NAMES:
            default = 1.0 if name == "phi" else 0.0
            raw = data.get(name, [default] * n)
            try:
                arr = np.asarray(raw, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                raise ConfigError(f"gain {name} must be a list of {n} numbers, got {raw!r}") from None
            if arr.size == 1:
                arr = np.full(n, arr[0])
            if arr.size != n:
                raise ConfigError(f"gain {name} needs {n} values (one per joint), got {arr.size}")
            if not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
                raise ConfigError(f"gain {name} must be finite and >= 0, got {arr.tolist()}")
            if name == "phi" and np.any(arr <= 0.0):
                raise ConfigError(f"boundary layer phi must be > 0, got {arr.tolist()}")
            values[name] = tuple(float(v) for v in arr)
        return cls(**values)

    def scaled(self, factors: Mapping[str, float]) -> Gains:
        """Gains with some parameters multiplied (Section 4.5.3)."""
        changes = {
            name: tuple(v * float(factor) for v in getattr(self, name))
            for name, factor in factors.items()
        }
        return dataclasses.replace(self, **changes)

    def matrix(self) -> np.ndarray:
        """``(5, n)`` array with rows kp, kd, ks, lam, phi (kernel layout)."""
        return np.array([self.kp, self.kd, self.ks, self.lam, self.phi], dtype=float)

    def as_dict(self) -> dict[str, list[float]]:
        return {name: list(getattr(self, name)) for name in GAIN_NAMES}


# --------------------------------------------------------------------------- #
# Run description
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class RunSpec:
    """Everything that defines one closed-loop run.

    Attributes
    ----------
    robot, contour, controller, scenario : str
        Preset names.
    gains : Gains
        Control parameters after the scenario's factors.
    rate : float
        Control rate (Hz); the plant is integrated with RK4 between control instants.
    sample_rate : float
        Rate (Hz) of the statistics samples over ``[0, T]``.
    payload : float
        Load (kg) of the simulated plant, placed as ``payload_reading`` says.
    payload_reading : str
        ``tip`` or ``link_com`` (:data:`PAYLOAD_READINGS`).
    duration_factor : float
        Multiplies the contour's duration.
    smc_model : dict
        Scales of the SMC's model estimate ``mass, coriolis, gravity, damping``.
    ellipse_error : str
        ``nearest`` or ``osculating`` (contour error of non-circular ellipses).
    waypoints_file : str or None
        CSV of task-space waypoints for ``contour == "csv"``.
    segment_duration : float
        Duration (s) of each segment of a CSV contour.
    """

    robot: str
    contour: str
    controller: str
    scenario: str
    gains: Gains
    rate: float
    sample_rate: float
    payload: float = 0.0
    payload_reading: str = "tip"
    duration_factor: float = 1.0
    smc_model: Mapping[str, float] = field(default_factory=lambda: dict(SMC_MODEL_DEFAULT))
    ellipse_error: str = "nearest"
    waypoints_file: str | None = None
    segment_duration: float = 2.0
    bound: float = 0.0

    def __post_init__(self) -> None:
        choice(self.robot, ROBOT_NAMES, "robot")
        choice(self.controller, CONTROLLER_NAMES, "controller")
        for label, value in (("rate", self.rate), ("sample_rate", self.sample_rate)):
            if not np.isfinite(value) or value <= 0.0:
                raise ConfigError(f"{label} must be a positive number of Hz, got {value!r}")
        ratio = self.rate / self.sample_rate
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ConfigError(
                f"rate ({self.rate:g} Hz) must be a whole multiple of the statistics rate "
                f"({self.sample_rate:g} Hz) so every sample falls on a control instant"
            )
        if not np.isfinite(self.payload) or self.payload < 0.0:
            raise ConfigError(f"payload must be >= 0 kg, got {self.payload!r}")
        choice(self.payload_reading, tuple(PAYLOAD_READINGS), "payload reading")
        if not np.isfinite(self.duration_factor) or self.duration_factor <= 0.0:
            raise ConfigError(f"duration_factor must be > 0, got {self.duration_factor!r}")
        unknown = set(self.smc_model) - set(SMC_MODEL_KEYS)
        if unknown:
            raise ConfigError(
                f"unknown smc_model key(s) {sorted(unknown)}; allowed: {', '.join(SMC_MODEL_KEYS)}"
            )
        for key, value in self.smc_model.items():
            if not isinstance(value, (int, float)) or not np.isfinite(value):
                raise ConfigError(f"smc_model.{key} must be a finite number, got {value!r}")

    @property
    def sample_every(self) -> int:
        return int(round(self.rate / self.sample_rate))

    def robot_model(self) -> Manipulator:
        """The simulated plant (with the scenario's payload, placed as ``payload_reading`` says)."""
        if self.payload_reading == "link_com":
            return make_robot(self.robot, params=loaded_params(self.robot, self.payload))
        return make_robot(self.robot, payload=self.payload, params=robot_params(self.robot))

    def nominal_model(self) -> Manipulator:
        """The model the SMC knows: the nominal robot (``tip``: never the payload;
        ``link_com``: rebuilt with the load on its link)."""
        if self.payload_reading == "link_com":
            return make_robot(self.robot, params=loaded_params(self.robot, self.payload))
        return make_robot(self.robot, params=robot_params(self.robot))

    def contour_model(self) -> Contour:
        return build_contour(
            self.robot,
            self.contour,
            ellipse_error=self.ellipse_error,
            waypoints_file=self.waypoints_file,
            segment_duration=self.segment_duration,
        ).scaled(self.duration_factor)

    def reference(self) -> JointReference:
        return JointReference(self.robot_model(), self.contour_model())

    def smc_model_vector(self) -> np.ndarray:
        """Kernel layout of :attr:`smc_model` (see :func:`kernels.control_torque`)."""
        m = {**SMC_MODEL_DEFAULT, **self.smc_model}
        return np.array([float(m[key]) for key in SMC_MODEL_KEYS], dtype=float)

    def describe(self) -> dict[str, Any]:
        """Plain-data description (stored in bags and reports)."""
        contour = self.contour_model()
        return {
            "package_version": __version__,
            "robot": self.robot,
            "contour": self.contour,
            "controller": self.controller,
            "scenario": self.scenario,
            "gains": self.gains.as_dict(),
            "control_rate_hz": self.rate,
            "sample_rate_hz": self.sample_rate,
            "payload_kg": self.payload,
            "payload_reading": self.payload_reading,
            "duration_factor": self.duration_factor,
            "duration_s": contour.duration,
            "smc_model": dict(self.smc_model),
            "contour_bound_m": self.bound,
            "contour_definition": contour.describe(),
            "ellipse_error": self.ellipse_error,
            "waypoints_file": self.waypoints_file,
            "segment_duration": self.segment_duration,
        }

    @classmethod
    def from_description(cls, data: Mapping[str, Any]) -> RunSpec:
        """Inverse of :meth:`describe` (used to rebuild a run from a bag)."""
        robot = data["robot"]
        return cls(
            robot=robot,
            contour=data["contour"],
            controller=data["controller"],
            scenario=data.get("scenario", "nominal"),
            gains=Gains(**{k: tuple(float(x) for x in data["gains"][k]) for k in GAIN_NAMES}),
            rate=float(data["control_rate_hz"]),
            sample_rate=float(data["sample_rate_hz"]),
            payload=float(data.get("payload_kg", 0.0)),
            payload_reading=data.get("payload_reading", "tip"),
            duration_factor=float(data.get("duration_factor", 1.0)),
            smc_model=dict(data.get("smc_model", {})),
            ellipse_error=data.get("ellipse_error", "nearest"),
            waypoints_file=data.get("waypoints_file"),
            segment_duration=float(data.get("segment_duration", 2.0)),
            bound=float(data.get("contour_bound_m", CONTOUR_BOUND[robot])),
        )


def control_steps(duration: float, rate: float) -> int:
    """Number of control periods covering ``[0, duration]``.

    Raises
    ------
    ConfigError
        If the run would hold more than :data:`MAX_CONTROL_STEPS` steps (checked
        before anything is allocated for them).
    """
    steps = duration * rate
    if not np.isfinite(steps) or steps > MAX_CONTROL_STEPS:
        raise ConfigError(
            f"rate {rate:g} Hz over {duration:g} s is {steps:.3g} control steps; a run holds at most "
            f"{MAX_CONTROL_STEPS:,} (lower the rate or the duration)"
        )
    return int(round(steps))


def robot_params(robot: str) -> RobotParams:
    data = load_config("robots")
    choice(robot, list(data), "robot")
    return RobotParams.from_mapping(data[robot], name=f"robots.yaml:{robot}")


def loaded_params(robot: str, payload: float) -> RobotParams:
    """Parameters of ``robot`` with ``payload`` kg added to the mass of the link that carries
    the end-effector (:data:`PAYLOAD_LINK`), at its centre of mass; its inertia unchanged."""
    params = robot_params(robot)
    links = list(params.links)
    k = PAYLOAD_LINK[robot]
    links[k] = dataclasses.replace(links[k], mass=links[k].mass + payload)
    return dataclasses.replace(params, links=tuple(links))


def contour_names(robot: str) -> tuple[str, ...]:
    return tuple(load_config("contours")[choice(robot, ROBOT_NAMES, "robot")]) + ("csv",)


def scenario_names() -> tuple[str, ...]:
    return tuple(load_config("scenarios"))


def build_contour(
    robot: str,
    name: str,
    *,
    ellipse_error: str = "nearest",
    waypoints_file: str | None = None,
    segment_duration: float = 2.0,
) -> Contour:
    """The named contour preset (or a CSV contour) for ``robot``."""
    dim = 3 if robot == "serial_3r" else 2
    if name == "csv":
        if not waypoints_file:
            raise ConfigError("contour 'csv' needs a waypoints file (--waypoints FILE)")
        from .trajectories import load_waypoints_csv

        pts = load_waypoints_csv(waypoints_file, dim=dim)
        return SegmentContour("csv", pts, segment_duration, metric="nearest")
    presets = load_config("contours")[choice(robot, ROBOT_NAMES, "robot")]
    spec = presets[choice(name, contour_names(robot), f"contour for {robot}")]
    if spec["type"] == "segments":
        pts = np.asarray(spec["waypoints"], dtype=float)
        if dim == 3:
            pts[:, 2] *= np.pi
        return SegmentContour(name, pts, float(spec["segment_duration"]))
    pose = None
    if dim == 3:
        pose = (float(spec["pose_pi"][0]) * np.pi, float(spec["pose_pi"][1]) * np.pi)
    return EllipseContour(
        name,
        spec["center"],
        float(spec["rx"]),
        float(spec["ry"]),
        float(spec["duration"]),
        pose=pose,
        ellipse_error=ellipse_error,
    )


def preset_gains(robot: str, contour: str, controller: str) -> Gains:
    """Gains of Table 4.16 / 4.33 for this robot, contour and controller."""
    choice(controller, CONTROLLER_NAMES, "controller")
    group = "linear" if contour == "csv" else load_config("contours")[robot][contour]["gain_group"]
    table = load_config("gains")[robot][group][controller]
    return Gains.from_mapping(table, 3 if robot == "serial_3r" else 2, controller)


def make_run(
    robot: str,
    contour: str,
    controller: str,
    *,
    scenario: str = "nominal",
    rate: float | None = None,
    gains: Gains | None = None,
    smc_model: Mapping[str, float] | None = None,
    ellipse_error: str = "nearest",
    waypoints_file: str | None = None,
    segment_duration: float = 2.0,
    sample_rate: float | None = None,
    payload_reading: str = "tip",
) -> RunSpec:
    """A run from preset names, with the scenario of Section 4.5 applied."""
    choice(robot, ROBOT_NAMES, "robot")
    choice(contour, contour_names(robot), f"contour for {robot}")
    choice(controller, CONTROLLER_NAMES, "controller")
    scenarios = load_config("scenarios")
    sc = scenarios[choice(scenario, list(scenarios), "scenario")] or {}
    base = gains or preset_gains(robot, contour, controller)
    factors = {
        k: v for k, v in (sc.get("gain_factors") or {}).items() if k in REQUIRED_GAINS[controller]
    }
    model = dict(load_config("gains").get("smc_model", {}))
    model.update(smc_model or {})
    return RunSpec(
        robot=robot,
        contour=contour,
        controller=controller,
        scenario=scenario,
        gains=base.scaled(factors),
        rate=float(rate or DEFAULT_CONTROL_RATE[robot]),
        sample_rate=float(sample_rate or SAMPLE_RATE[robot]),
        payload=float(sc.get("payload", 0.0)),
        payload_reading=payload_reading,
        duration_factor=float(sc.get("duration_factor", 1.0)),
        smc_model=model,
        ellipse_error=ellipse_error,
        waypoints_file=waypoints_file,
        segment_duration=segment_duration,
        bound=CONTOUR_BOUND[robot],
    )


def smc_reading(name: str) -> dict[str, float]:
    """Model-estimate scales of a named SMC reading (``config/smc_readings.yaml``)."""
    readings = load_config("smc_readings")
    return dict(readings[choice(name, list(readings), "SMC reading")]["model"])
