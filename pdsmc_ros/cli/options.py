"""The arguments the ``pdsmc`` subcommands share: value types that refuse bad input in one line,
the run's flags, and the run they name (:func:`spec_from_args`, through the one run builder
:func:`~pdsmc_ros.presets.make_run`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import numpy as np

from ..arguments import gain_value, positive_float
from ..errors import ConfigError

if TYPE_CHECKING:
    from ..presets import RunSpec


def whole_number(text: str, lowest: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= {lowest}, got {text!r}") from None
    if value < lowest:
        raise argparse.ArgumentTypeError(f"expected a whole number >= {lowest}, got {text!r}")
    return value


def positive_int(text: str) -> int:
    return whole_number(text, 1)


MAX_VALUES = 1000
"""Values one sweep may take (one run each)."""

MAX_WORKERS = 256
"""Processes a command may start (each holds its own compiled kernels and run arrays)."""


def count_at_most(text: str, most: int, what: str) -> int:
    """A whole number from 1 to ``most`` (``what`` names the unit in the error)."""
    value = positive_int(text)
    if value > most:
        raise argparse.ArgumentTypeError(f"expected at most {most:,} {what}, got {text!r}")
    return value


def worker_count(text: str) -> int:
    return count_at_most(text, MAX_WORKERS, "processes")


def value_list(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
    if not values or any(not np.isfinite(v) or v < 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers >= 0, got {text!r}")
    if len(values) > MAX_VALUES:
        raise argparse.ArgumentTypeError(f"expected at most {MAX_VALUES} values (one run each), got {len(values)}")
    return values


MAX_RUNS = 1_000_000


def run_count(text: str) -> int:
    return count_at_most(text, MAX_RUNS, "runs")


def seed_value(text: str) -> int:
    return whole_number(text, 0)


def name_list(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names or len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(f"expected distinct comma-separated names, got {text!r}")
    return names


def add_engine_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scheduler", default=None,
                   help="a Dask scheduler, tcp://HOST:PORT (default: a local cluster of --workers processes)")
    p.add_argument("--workers", type=worker_count, default=None, help="local cluster processes (default: cores)")


def add_payload_reading(p: argparse.ArgumentParser) -> None:
    p.add_argument("--payload-reading", choices=("tip", "link_com"), default="tip",
                   help="where the payload scenario puts its load: tip (point mass at the end-effector, "
                   "default) or link_com (on the last link's centre of mass, the SMC's model rebuilt for it)")


def whole_number_from_zero(text: str) -> int:
    return whole_number(text, 0)


def add_loop_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mode", choices=("realtime", "lockstep"), default="realtime",
                   help="the loop the gains must hold in: realtime (default: zero-order hold plus two periods of "
                   "delay, the controller's and the plant's sampling, as on a robot) or lockstep (zero-order hold, "
                   "no delay)")
    p.add_argument("--delay-periods", type=whole_number_from_zero, default=0,
                   help="periods of delay beyond the mode's own (a driver's, a network's; default 0)")
    p.add_argument("--margin", type=positive_float, default=None,
                   help="required rate / lowest stable rate (default 2 in realtime, 1 in lockstep)")


def add_model_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", default=None, metavar="ROBOT",
                   help="the arm model the model-based laws use instead of --robot's own, e.g. pdsmc identify's "
                   "DIR/identified.yaml (or .urdf): the same joints; the simulated arm stays --robot (with "
                   "--smc-reading exact the laws take it as it is)")


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    # robots and laws are checked against their registries when the run is built (importing them here
    # would load numba for every command, --help included)
    p.add_argument("--robot", required=True,
                   help="serial_3r, parallel_5r, an arm of example-robot-data (ur5, panda, ...) or a .urdf file")
    p.add_argument(
        "--contour",
        required=True,
        help="zigzag, diamond, circle, ellipse (serial); circle, ellipse_horizontal, "
        "ellipse_vertical (parallel); or csv with --waypoints",
    )
    p.add_argument("--controller", required=True, help="a registered control law: pd, smc, pdsmc, ...")
    p.add_argument("--scenario", default="nominal",
                   help="nominal, high_speed, payload, high_pd, high_smc (config/scenarios.yaml)")
    p.add_argument("--rate", type=positive_float, default=None,
                   help="control rate in Hz (default 10000 serial, 5000 parallel)")
    p.add_argument("--smc-reading", default="literal",
                   help="SMC model estimate from config/smc_readings.yaml (default: literal)")
    add_payload_reading(p)
    p.add_argument("--ellipse-error", choices=("nearest", "osculating"), default="nearest",
                   help="contour error of ellipses: exact nearest point or osculating circle")
    p.add_argument("--waypoints", default=None, help="CSV of task-space waypoints (--contour csv)")
    p.add_argument("--segment-duration", type=positive_float, default=2.0,
                   help="seconds per segment of a CSV contour (default 2)")
    p.add_argument("--params-file", default=None,
                   help="gains from a ROS 2 params file (the controller's, e.g. written by pdsmc tune)")
    p.add_argument("--gain", type=gain_value, action="append", default=None, metavar="NAME=V1,V2,...",
                   help="one gain the law declares (its -p NAME:= parameter), one value per joint; repeat for "
                   "others; replaces the preset's and the params file's, before the scenario's factors")
    add_model_argument(p)
    p.add_argument("--no-enforce-limits", action="store_true",
                   help="do not clamp the torque to the arm's effort limits (URDF <limit effort>, "
                   "config/robots.yaml); the clamp is on by default")


FILE_SETTINGS = {"robot": "--robot", "contour": "--contour", "type": "--controller", "scenario": "--scenario"}
"""Run parameters of a params file that a flag also sets: they must agree."""


def spec_from_args(args: argparse.Namespace) -> RunSpec:
    from ..control import law
    from ..presets import make_run, smc_reading

    params = None
    rate = args.rate
    if args.params_file:
        from ..experiments.tuning import controller_parameters, read_params_file
        from ..robots import make_robot
        from ..robots.catalog import resolve_robot
        from ..robots.options import same_robot

        given = controller_parameters(args.params_file)
        flags = {"robot": args.robot, "contour": args.contour, "type": args.controller, "scenario": args.scenario}
        for key, flag in FILE_SETTINGS.items():
            same = given.get(key, flags[key]) == flags[key] or (key == "robot" and same_robot(given[key], flags[key]))
            if not same:
                raise ConfigError(f"params file {args.params_file!r} sets {key}: {given[key]} but {flag} is "
                                  f"{flags[key]}: give the same, or leave one out")
        if rate is None and given.get("rate"):  # the rate the file's gains were chosen for
            rate = positive_float(str(given["rate"]))
        params = read_params_file(args.params_file, make_robot(resolve_robot(args.robot)).n, args.controller)
    return make_run(
        args.robot,
        args.contour,
        args.controller,
        scenario=args.scenario,
        rate=rate,
        smc_model=smc_reading(args.smc_reading) if law(args.controller).model_based else None,
        ellipse_error=args.ellipse_error,
        waypoints_file=args.waypoints,
        segment_duration=args.segment_duration,
        payload_reading=args.payload_reading,
        params=params,
        overrides=dict(args.gain or ()),
        model=args.model,
    )


RUN_DEFAULTS = {"scenario": "nominal", "rate": None, "smc_reading": "literal", "ellipse_error": "nearest",
                 "waypoints": None, "segment_duration": 2.0, "payload_reading": "tip", "no_enforce_limits": False,
                 "gain": None, "model": None}
"""The run arguments montecarlo does not take (its runs are nominal, at the robot's rate)."""


def file_controller(path: str, controllers: list[str]) -> str:
    """The law whose gains a params file holds (its ``type``), one of ``controllers``."""
    from ..experiments.tuning import controller_parameters

    controller = controller_parameters(path).get("type")
    if controller not in controllers:
        raise ConfigError(f"params file {path!r} holds gains for type {controller!r}; --controllers is "
                          f"{','.join(controllers)}: name it there (or add type: to the file)")
    return str(controller)


