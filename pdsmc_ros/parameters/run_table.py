"""A run's settings, written once (ROS-free, light: the command line reads it for its options).

Each setting's name, type, default, bounds, choices, description and ``pdsmc`` option is one row
of :data:`RUN`; from it come the nodes' run parameters (:func:`run_parameters`, part of every node's
table in :mod:`.tables`), ``pdsmc``'s run options (:func:`pdsmc_ros.cli.options.add_run_arguments`),
the defaults of :class:`~pdsmc_ros.runs.RunSpec` and :func:`~pdsmc_ros.runs.make_run`
(:data:`RUN_DEFAULTS`), the params-file check and the generated references. What depends on the
registries (the robots, laws, scenarios and readings a setting accepts) is read when asked.
"""

from __future__ import annotations

from ..config import load_config
from .declaration import ParameterSpec

P = ParameterSpec


def _robots() -> str:
    from ..robots.catalog import allowed_robots  # the registries load numba: read when asked

    return allowed_robots()


def _laws() -> tuple[str, ...]:
    from ..control.registry import law_names

    return law_names()


def _modes() -> tuple[str, ...]:
    from ..control.stability import MODES

    return MODES


def _ellipse_errors() -> tuple[str, ...]:
    from ..contours.shapes import ELLIPSE_ERRORS  # the contours load numba: read when asked

    return ELLIPSE_ERRORS


def _scenarios() -> tuple[str, ...]:
    return tuple(load_config("scenarios"))


def _smc_readings() -> tuple[str, ...]:
    return tuple(load_config("smc_readings"))


PAYLOAD_READINGS = {
    "tip": "a point mass at the end-effector; the SMC's model estimate stays the nominal robot's",
    "link_com": "the load added to the mass of the link that carries the end-effector (serial "
    "link 3, five-bar link 3), at that link's centre of mass with its inertia unchanged; the "
    "SMC's model estimate is rebuilt with it",
}
"""Readings of Section 4.5.2's "a simulated load of 1.5 kg was added at the end-effector"
(``payload_reading``); ``tip`` is the physical one and the default."""

RUN = (
    P("robot", "string", "serial_3r", "the arm: serial_3r, parallel_5r, an arm of example-robot-data (ur5, "
      "panda, ...) or a .urdf file", constraints=lambda: "one of: " + _robots(), flag="--robot"),
    P("contour", "string", "circle", "contour preset (config/contours.yaml: zigzag, diamond, circle, ellipse on the "
      "serial arm; circle, ellipse_horizontal, ellipse_vertical on the five-bar), or csv with the waypoints",
      flag="--contour"),
    P("type", "string", "pdsmc", "the control law (a registered law: pd, smc, pdsmc, ...)",
      constraints=lambda: "one of: " + ", ".join(_laws()), flag="--controller"),
    P("scenario", "string", "nominal", "robustness scenario (config/scenarios.yaml: nominal, high_speed, payload, "
      "high_pd, high_smc)", constraints=lambda: "one of: " + ", ".join(_scenarios()), flag="--scenario"),
    P("mode", "string", "lockstep", "timing mode", choices=_modes),
    P("rate", "double", 0.0, "control rate in Hz (0: the robot's, 10 kHz serial / 5 kHz parallel)", lo=0.0, hi=1.0e6,
      flag="--rate"),
    P("sample_rate", "double", 0.0, "statistics rate in Hz (0: the thesis's)", lo=0.0, hi=1.0e6),
    P("duration_factor", "double", 1.0, "multiplies the contour duration (after the scenario's factor)", lo=0.001,
      hi=1000.0),
    P("smc_reading", "string", "literal", "SMC model estimate (config/smc_readings.yaml)",
      constraints=lambda: "one of: " + ", ".join(_smc_readings()), flag="--smc-reading"),
    P("payload_reading", "string", "tip", "where the payload scenario puts its load: tip (a point mass at the "
      "end-effector) or link_com (on the last link's centre of mass, the SMC's model rebuilt for it)",
      choices=tuple(PAYLOAD_READINGS), flag="--payload-reading", node=False),
    P("ellipse_error", "string", "nearest", "contour error of ellipses: the exact nearest point or the osculating "
      "circle", choices=_ellipse_errors, flag="--ellipse-error"),
    P("waypoints_file", "string", "", "CSV of task-space waypoints for contour csv", flag="--waypoints"),
    P("segment_duration", "double", 2.0, "seconds per segment of a CSV contour", lo=0.001, hi=1000.0,
      flag="--segment-duration"),
    P("clock_rate", "double", 100.0, "lockstep: /clock publication rate in sim-time Hz", lo=1.0, hi=1.0e6),
)
"""A run's settings, each written once: the nodes declare those with :attr:`ParameterSpec.node`
(:func:`run_parameters`), ``pdsmc``'s run options are those with a :attr:`ParameterSpec.flag`,
:class:`~pdsmc_ros.runs.RunSpec` and :func:`~pdsmc_ros.runs.make_run` take their defaults from
:data:`RUN_DEFAULTS`, and the reference pages are generated from it."""

RUN_DEFAULTS = {spec.name: spec.default for spec in RUN}
"""Each run setting's default, by name."""


def run_parameters() -> tuple[ParameterSpec, ...]:
    """The parameters that define a run (every node of it but the MuJoCo stand-in)."""
    return tuple(spec for spec in RUN if spec.node)


