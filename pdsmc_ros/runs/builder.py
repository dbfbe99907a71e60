"""YAML presets (``config/``), the description of one run, and the one run builder (:func:`make_run`).

A :class:`RunSpec` names everything a run needs -- robot, contour, controller,
gains, scenario, rates -- as plain data, so the same description drives the
in-process simulator, the ROS nodes (as parameters) and the bag metadata.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import __version__
from ..config import choice, load_config
from ..contours import Contour, JointReference
from ..contours.presets import contour_names, contour_preset, contour_set
from ..control.registry import GAINS, SMC_MODEL_KEYS, Gains, law, smc_model_vector
from ..errors import ConfigError, InvalidInputError, MissingGainsError
from ..parameters.run_table import PAYLOAD_READINGS, RUN_DEFAULTS, run_parameters
from ..robots import ROBOTS, Manipulator, RobotParams, make_robot, robot_settings
from ..robots.base import FloatArray
from ..robots.catalog import resolve_model, resolve_robot

__all__ = [
    "MAX_CONTROL_STEPS",
    "PAYLOAD_READINGS",
    "RunSpec",
    "build_contour",
    "contour_names",
    "contour_set",
    "control_steps",
    "loaded_params",
    "make_run",
    "preset_gains",
    "resolve_gains",
    "run_from_parameters",
    "run_from_settings",
    "scenario_gain_factors",
    "scenario_names",
    "smc_model_default",
    "smc_reading",
]
"""The run builder's names (the contour presets' from :mod:`.contour_presets`, kept importable here)."""

MAX_CONTROL_STEPS = 10_000_000
"""Control steps one run may hold: the sampled reference and its temporaries take about
400 bytes a step (4 GB here), 200 times the thesis's 50,001-step serial runs."""

DEFAULT = RUN_DEFAULTS
"""The run's defaults: the parameter table's (:data:`pdsmc_ros.parameters.tables.RUN`), written there once."""


def smc_model_default() -> dict[str, float]:
    """The SMC's model estimate of Sections 4.3/4.4 (``config/gains.yaml``, ``smc_model``)."""
    return {k: float(v) for k, v in load_config("gains")["smc_model"].items()}


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
    enforce_limits : bool
        Clamp the controller's torque to the arm's effort limits (``robot.effort_limits``) at
        every step; False opts out (``--no-enforce-limits``, ``enforce_limits:=false``).
    model : str or None
        The robot whose model the law knows (``--model``: an identified arm, say), with the same
        joints as ``robot``; None: ``robot``'s own (the simulated plant stays ``robot``).
    """

    robot: str
    contour: str
    controller: str
    scenario: str
    gains: Gains
    rate: float
    sample_rate: float
    payload: float = 0.0
    payload_reading: str = DEFAULT["payload_reading"]
    duration_factor: float = DEFAULT["duration_factor"]
    smc_model: Mapping[str, float] = field(default_factory=smc_model_default)
    ellipse_error: str = DEFAULT["ellipse_error"]
    waypoints_file: str | None = None
    segment_duration: float = DEFAULT["segment_duration"]
    bound: float = 0.0
    enforce_limits: bool = True
    model: str | None = None

    def __post_init__(self) -> None:
        resolve_robot(self.robot)
        if self.model is not None:
            known = make_robot(resolve_model(self.model)).joint_names
            own = make_robot(resolve_robot(self.robot)).joint_names
            if tuple(known) != tuple(own):
                raise ConfigError(f"model {self.model!r} has joints {list(known)}; robot {self.robot!r} has "
                                  f"{list(own)}: a model of this arm has its joints, in its order")
        law(self.controller)
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
        return make_robot(self.robot, payload=self.payload)

    def nominal_model(self) -> Manipulator:
        """The model the SMC knows: :attr:`model` if given, else the nominal robot (``tip``: never
        the payload; ``link_com``: rebuilt with the load on its link)."""
        if self.model is not None:
            return make_robot(resolve_model(self.model))
        if self.payload_reading == "link_com":
            return make_robot(self.robot, params=loaded_params(self.robot, self.payload))
        return make_robot(self.robot)

    def contour_model(self) -> Contour:
        return build_contour(
            self.robot,
            self.contour,
            ellipse_error=self.ellipse_error,
            waypoints_file=self.waypoints_file,
            segment_duration=self.segment_duration,
        ).scaled(self.duration_factor)

    def robot_description(self) -> str:
        """The URDF of the simulated robot (the plant's ``/robot_description``)."""
        return make_robot(self.robot).description(self.payload)

    def reference(self) -> JointReference:
        return JointReference(self.robot_model(), self.contour_model())

    def smc_model_vector(self) -> np.ndarray:
        """:attr:`smc_model` as :attr:`pdsmc_ros.control.LawSetup.smc_model`."""
        return smc_model_vector({**smc_model_default(), **self.smc_model})

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
            "enforce_limits": self.enforce_limits,
            **({} if self.model is None else {"model": self.model}),
        }

    @classmethod
    def from_description(cls, data: Mapping[str, Any]) -> RunSpec:
        """Inverse of :meth:`describe` (used to rebuild a run from a bag)."""
        robot = resolve_robot(data["robot"])
        return cls(
            robot=robot,
            contour=data["contour"],
            controller=data["controller"],
            scenario=data.get("scenario", DEFAULT["scenario"]),
            gains=Gains.from_mapping(data["gains"], make_robot(robot).n, data["controller"]),
            rate=float(data["control_rate_hz"]),
            sample_rate=float(data["sample_rate_hz"]),
            payload=float(data.get("payload_kg", 0.0)),
            payload_reading=data.get("payload_reading", DEFAULT["payload_reading"]),
            duration_factor=float(data.get("duration_factor", DEFAULT["duration_factor"])),
            smc_model=dict(data.get("smc_model", {})),
            ellipse_error=data.get("ellipse_error", DEFAULT["ellipse_error"]),
            waypoints_file=data.get("waypoints_file"),
            segment_duration=float(data.get("segment_duration", DEFAULT["segment_duration"])),
            bound=float(data.get("contour_bound_m", robot_settings(robot).contour_bound)),
            enforce_limits=bool(data.get("enforce_limits", True)),
            model=data.get("model"),
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


def loaded_params(robot: str, payload: float) -> RobotParams:
    """Parameters of ``robot`` with ``payload`` kg added to the mass of the link that carries
    the end-effector (the robot's ``payload_link``), at its centre of mass; its inertia unchanged."""
    try:
        return make_robot(robot).payload_params(payload)
    except InvalidInputError as exc:
        raise ConfigError(str(exc)) from None


def scenario_names() -> tuple[str, ...]:
    return tuple(load_config("scenarios"))


def preset_gains(robot: str, contour: str, controller: str) -> Gains:
    """Gains of Table 4.16 / 4.33 for this robot, contour and controller; a law without its own that
    declares :attr:`LawEntry.presets_from` takes that law's (:meth:`LawEntry.presets_of`), derived at
    this contour's start (``csv``, ``joints``: at the start of the robot's first linear contour)."""
    entry = law(controller)
    model = make_robot(resolve_robot(robot))
    contours = load_config("contours").get(model.contour_set(), {})
    group = "linear" if contour in ("csv", "joints") else contours[contour]["gain_group"]
    source = model.gains_source()
    tables = source if isinstance(source, Mapping) else load_config("gains").get(source, {})
    table = tables.get(group, {}).get(controller)
    other = tables.get(group, {}).get(entry.presets_from) if entry.presets_from else None
    start = contour if contour in contours else next((c for c, v in contours.items() if v["gain_group"] == group), None)
    if table is None and other is not None and start is not None:
        table = entry.presets_of(other, model, _start_configuration(robot, start, id(ROBOTS[resolve_robot(robot)])))
    if table is None:
        raise MissingGainsError(f"config/gains.yaml has no {controller} gains for {robot} ({group} contours); "
                          "give the gains, or let `pdsmc tune` propose them")
    return Gains.from_mapping(table, model.n, controller)


def build_contour(robot: str, name: str, *, ellipse_error: str = DEFAULT["ellipse_error"],
                  waypoints_file: str | None = None,
                  segment_duration: float = DEFAULT["segment_duration"]) -> Contour:
    """The contour ``name`` (a preset, ``csv`` or ``joints``) for ``robot``, the settings not given at
    the run table's defaults (:func:`pdsmc_ros.contours.presets.contour_preset`)."""
    return contour_preset(robot, name, ellipse_error=ellipse_error, waypoints_file=waypoints_file,
                          segment_duration=segment_duration)


@functools.lru_cache(maxsize=64)
def _start_configuration(robot: str, contour: str, entry: int) -> FloatArray:  # noqa: ARG001 - entry: the cache key
    """The joint reference's first point of a preset contour (``entry``, the id of what the registry
    holds for the robot, keys a name registered anew)."""
    start: FloatArray = JointReference(make_robot(robot), build_contour(robot, contour)).sample([0.0]).q[0]
    return start


def resolve_gains(robot: str, contour: str, controller: str, *, scenario: str = "nominal",
                  gains: Gains | None = None, layers: Sequence[Mapping[str, Any]] = (),
                  joint_order: Sequence[int] | None = None, needs_gains: bool = True) -> Gains:
    """The gains of a run: the one resolver, used by every entry point (``pdsmc simulate`` and the
    other commands through :func:`make_run`, the controller node at start-up and on ``ros2 param set``).

    In this order, each layer replacing the gains it names: (1) ``gains`` if given, else the
    presets (``config/gains.yaml``, Tables 4.16 / 4.33; an arm may have none); (2) each of
    ``layers`` in turn -- a params file's gains, then explicit overrides (``-p kp:=``, ``--gain
    kp=``, ``ros2 param set``), each given in ``joint_order`` (``joint_order[i]``: the robot index
    of the ``i``-th value, the controller's ``joints``; None: robot order) and put in robot order
    (one value stands for every joint; an empty one is not given); (3) the scenario's gain factors
    (Section 4.5.3, :func:`scenario_gain_factors`) on the result, whichever layer gave each gain:
    a params file's ``kp`` under ``high_pd`` is scaled exactly as the preset's would be. Every gain
    the law declares as needed must come from some layer; when ``needs_gains`` is False (the nodes
    other than the controller, which never use them) the missing ones hold their neutral values.

    Where they go: the run's :class:`RunSpec` (``gains``); the controller's core
    (:class:`~pdsmc_ros.controller.core.ControllerCore`) builds its law from it at start-up and on
    a set (:meth:`~pdsmc_ros.control.law.ControlLaw.from_spec`), whose compiled call hands the rows
    ``kp, kd, ...`` to the law's formula (:mod:`pdsmc_ros.control.laws` for the thesis's).

    Raises
    ------
    ConfigError
        A gain the law does not declare, a value out of its bounds or of the wrong length, or
        (``needs_gains``) a gain given by no layer.
    """
    entry = law(controller)
    n = make_robot(resolve_robot(robot)).n
    try:
        base = (gains if gains is not None else preset_gains(robot, contour, controller)).as_dict()
    except MissingGainsError:
        base = {}  # an arm or a law without presets: the layers give them
    given: dict[str, Any] = dict(base)
    for layer in layers:
        for name, value in layer.items():
            values = _in_robot_order(value, joint_order, n)
            if values is not None:
                given[name] = values
    missing = [g for g in entry.gain_names if g not in given]
    if missing and needs_gains:
        raise MissingGainsError(
            f"{controller} needs gains {', '.join(missing)}: this arm has no preset for {contour} (config/gains.yaml "
            f"has no {controller} gains for {robot}); give them (-p {missing[0]}:=[...] or --gain {missing[0]}=...) "
            "or a params file (pdsmc tune writes one)")
    neutral = {g.name: [g.neutral] for g in entry.specs if g.name in missing}
    return Gains.from_mapping({**neutral, **given}, n, controller).scaled(scenario_gain_factors(scenario, controller))


def _in_robot_order(value: Any, joint_order: Sequence[int] | None, n: int) -> Any:
    """A layer's gain in robot order: a number is one value (for every joint), an empty list is
    not given (None); a list of ``n`` numbers in ``joint_order`` is permuted; anything else is left
    for :meth:`Gains.from_mapping` to refuse with its message."""
    if value is None:
        return None
    if isinstance(value, int | float) and not isinstance(value, bool):
        return [float(value)]
    if isinstance(value, str | bytes) or not isinstance(value, Sequence | np.ndarray):
        return value
    values = list(value)
    if not values:
        return None
    if joint_order is not None and len(values) == n and len(joint_order) == n \
            and all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        robot = [0.0] * n
        for i, v in zip(joint_order, values, strict=True):
            robot[int(i)] = float(v)
        return robot
    return values


def make_run(
    robot: str,
    contour: str,
    controller: str,
    *,
    scenario: str = DEFAULT["scenario"],
    rate: float | None = None,
    gains: Gains | None = None,
    params: Mapping[str, Any] | None = None,
    overrides: Mapping[str, Any] | None = None,
    needs_gains: bool = True,
    joint_order: Sequence[int] | None = None,
    smc_model: Mapping[str, float] | None = None,
    ellipse_error: str = DEFAULT["ellipse_error"],
    waypoints_file: str | None = None,
    segment_duration: float = DEFAULT["segment_duration"],
    sample_rate: float | None = None,
    payload_reading: str = DEFAULT["payload_reading"],
    duration_factor: float = DEFAULT["duration_factor"],
    model: str | None = None,
) -> RunSpec:
    """The one run builder (the CLI, the nodes, tune, sweep, Monte Carlo and reproduce use it).

    The gains come from :func:`resolve_gains`: ``gains`` or the presets, then ``params`` (a params
    file's gains), then ``overrides`` (explicit ``-p``/``--gain`` values), both in ``joint_order``
    if given (the controller's ``joints``), then the scenario's gain factors; the scenario of
    Section 4.5 also sets the payload and its duration factor, which ``duration_factor``
    multiplies. Rates not given are the robot's settings. The defaults are the parameter table's
    (:data:`DEFAULT`); :func:`run_from_settings` builds the run a node's parameters or the
    command line's options name.
    ``model``: the robot whose model the law knows (:attr:`RunSpec.model`).
    """
    choice(contour, contour_names(robot), f"contour for {robot}")
    settings = robot_settings(robot)
    scenarios = load_config("scenarios")
    sc = scenarios[choice(scenario, list(scenarios), "scenario")] or {}
    resolved = resolve_gains(robot, contour, controller, scenario=scenario, gains=gains,
                             layers=[x for x in (params, overrides) if x], joint_order=joint_order,
                             needs_gains=needs_gains)
    estimate = smc_model_default()
    estimate.update(smc_model or {})
    return RunSpec(
        robot=robot,
        contour=contour,
        controller=controller,
        scenario=scenario,
        gains=resolved,
        rate=float(rate or settings.control_rate),
        sample_rate=float(sample_rate or settings.sample_rate),
        payload=float(sc.get("payload", 0.0)),
        payload_reading=payload_reading,
        duration_factor=float(sc.get("duration_factor", 1.0)) * float(duration_factor),
        smc_model=estimate,
        ellipse_error=ellipse_error,
        waypoints_file=waypoints_file,
        segment_duration=segment_duration,
        bound=settings.contour_bound,
        model=model,
    )


def run_from_settings(settings: Mapping[str, Any], *, params: Mapping[str, Any] | None = None,
                      overrides: Mapping[str, Any] | None = None, needs_gains: bool = True,
                      joint_order: Sequence[int] | None = None, model: str | None = None) -> RunSpec:
    """The run that the run table's settings name (:data:`pdsmc_ros.parameters.tables.RUN`, by
    parameter name: a node's declared values, the command line's options): :func:`make_run` with
    each setting not given (absent or None) at its default, a rate of 0 the robot's, an empty
    ``waypoints_file`` none, and the SMC reading's model estimate for a model-based law. ``params``,
    ``overrides``, ``needs_gains``, ``joint_order`` and ``model``: as :func:`make_run` takes them.

    Raises
    ------
    ConfigError
        A setting the builder refuses (an unknown robot, contour, law, scenario or reading).
    """
    v = {**DEFAULT, **{k: x for k, x in settings.items() if x is not None}}
    return make_run(v["robot"], v["contour"], v["type"], scenario=v["scenario"], rate=v["rate"] or None,
                    sample_rate=v["sample_rate"] or None,
                    smc_model=smc_reading(v["smc_reading"]) if law(v["type"]).model_based else None,
                    ellipse_error=v["ellipse_error"], waypoints_file=v["waypoints_file"] or None,
                    segment_duration=v["segment_duration"], payload_reading=v["payload_reading"],
                    duration_factor=v["duration_factor"], params=params, overrides=overrides,
                    needs_gains=needs_gains, joint_order=joint_order, model=model)


def run_from_parameters(values: Mapping[str, Any], *, needs_gains: bool = True,
                        joint_order: Sequence[int] | None = None) -> RunSpec:
    """The run a node's declared parameter ``values`` name (by name; None: not set).

    The run table's settings go to :func:`run_from_settings`; the gains given (``-p kp:=``, a
    params file: rcl merges both) are the overrides layer of :func:`resolve_gains`, in
    ``joint_order`` (the controller's ``joints``), put in robot order, over the presets, then
    scaled by the scenario's factors, as in-process. An arm without preset gains needs them all
    given when ``needs_gains`` (the controller); the other nodes run with neutral placeholders.

    Raises
    ------
    ConfigError
        ``parameters: `` and a message naming the parameter and what is allowed.
    """
    overrides = {name: values[name] for name in GAINS if values.get(name) is not None}
    settings = {spec.name: values[spec.name] for spec in run_parameters()}
    try:
        return run_from_settings(settings, overrides=overrides, needs_gains=needs_gains, joint_order=joint_order)
    except ConfigError as exc:
        raise ConfigError(f"parameters: {exc}") from None


def scenario_gain_factors(scenario: str, controller: str) -> dict[str, float]:
    """The factors ``scenario`` multiplies ``controller``'s gains by (Section 4.5.3), by gain name:
    :func:`resolve_gains` applies them to the gains given (a params file, ``-p``, ``ros2 param set``)
    as to the presets."""
    scenarios = load_config("scenarios")
    sc = scenarios[choice(scenario, list(scenarios), "scenario")] or {}
    factors = sc.get("gain_factors") or {}
    return {g.name: float(factors[g.factor_key]) for g in law(controller).specs if g.factor_key in factors}


def smc_reading(name: str) -> dict[str, float]:
    """Model-estimate scales of a named SMC reading (``config/smc_readings.yaml``)."""
    readings = load_config("smc_readings")
    return dict(readings[choice(name, list(readings), "SMC reading")]["model"])
