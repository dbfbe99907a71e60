"""The arguments the ``pdsmc`` subcommands share: value types that refuse bad input in one line,
the run's flags, and the run they name (:func:`spec_from_args`, through the one run builder
:func:`~pdsmc_ros.runs.builder.make_run`)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arguments import gain_value, positive_float
from ..errors import ConfigError
from ..parameters.declaration import ParameterSpec
from ..parameters.run_table import RUN
from ..parameters.tables import REALISM_PRESETS

if TYPE_CHECKING:
    from ..runs.builder import RunSpec


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
    """``--payload-reading``, from the run table's row."""
    add_run_option(p, run_setting("payload_reading"))


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
    p.add_argument("--realism", choices=REALISM_PRESETS, default=None,
                   help="the arm is the MuJoCo stand-in under this preset of its nuisances (docs/how-to/mujoco.md): "
                   "the check adds its command delay to the loop's, sees the velocity as its drive estimates it "
                   "(differenced, low-pass filtered) and gives the plant the arm's viscous damping (the description's "
                   "plus the preset's friction_viscous); pdsmc tune also runs each candidate against it")


def add_model_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", default=None, metavar="ROBOT",
                   help="the arm model the model-based laws use instead of --robot's own, e.g. pdsmc identify's "
                   "DIR/identified.yaml (or .urdf): the same joints; the simulated arm stays --robot (with "
                   "--smc-reading exact the laws take it as it is)")


REQUIRED = ("robot", "contour", "type")
"""Run settings a ``pdsmc`` command needs named (a node takes the table's default)."""


def run_setting(name: str) -> ParameterSpec:
    """The run table's row ``name`` (:data:`pdsmc_ros.parameters.tables.RUN`)."""
    return next(spec for spec in RUN if spec.name == name)


def option_value(spec: ParameterSpec) -> Callable[[str], Any]:
    """The option's value from its text, checked by its row (bounds, choices): one line if refused."""

    def value(text: str) -> Any:
        try:
            number = float(text) if spec.type == "double" else text
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {spec.allowed()}, got {text!r}") from None
        reason = spec.problem(number)
        if reason:
            raise argparse.ArgumentTypeError(f"expected {spec.allowed()}, got {text!r}")
        return number

    value.__name__ = spec.type  # argparse names the type in its own messages
    return value


def add_run_option(p: argparse.ArgumentParser, spec: ParameterSpec) -> None:
    """The option of one run setting (its :attr:`~pdsmc_ros.parameters.ParameterSpec.flag`), derived from
    its row: help, default, choices and check."""
    choices = spec.choices if isinstance(spec.choices, tuple) and spec.choices else None
    if spec.name in REQUIRED:
        p.add_argument(spec.flag, required=True, help=spec.description)
        return
    if spec.default in ("", None):
        default, shown = None, ""
    else:
        default = spec.default
        shown = f" (default {spec.default:g})" if spec.type == "double" else f" (default {spec.default})"
    p.add_argument(spec.flag, default=default, choices=choices, type=None if choices else option_value(spec),
                   help=spec.description + shown)


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """The run's options: one per row of the run table with a flag (robots and laws are checked
    against their registries when the run is built: importing them here would load numba for every
    command, --help included), then the gains' options and the limits' opt-out."""
    for spec in RUN:
        if spec.flag:
            add_run_option(p, spec)
    p.add_argument("--params-file", default=None,
                   help="gains from a ROS 2 params file (the controller's, e.g. written by pdsmc tune)")
    p.add_argument("--gain", type=gain_value, action="append", default=None, metavar="NAME=V1,V2,...",
                   help="one gain the law declares (its -p NAME:= parameter), one value per joint; repeat for "
                   "others; replaces the preset's and the params file's, before the scenario's factors")
    add_model_argument(p)
    p.add_argument("--no-enforce-limits", action="store_true",
                   help="do not clamp the torque to the arm's effort limits (URDF <limit effort>, "
                   "config/robots.yaml); the clamp is on by default")


def dest(spec: ParameterSpec) -> str:
    """The attribute of the parsed arguments that holds a run setting (``--controller``: ``controller``)."""
    return spec.flag.removeprefix("--").replace("-", "_")


FILE_SETTINGS = {"robot": "--robot", "contour": "--contour", "type": "--controller", "scenario": "--scenario"}
"""Run parameters of a params file that a flag also sets: they must agree."""


def spec_from_args(args: argparse.Namespace) -> RunSpec:
    """The run the options name, through the one builder
    (:func:`~pdsmc_ros.runs.builder.run_from_settings`): the run table's settings, a params file's gains
    (its run settings must agree with the options; its rate is taken when ``--rate`` is not given), then
    the ``--gain`` overrides."""
    from ..runs.builder import run_from_settings

    settings = {spec.name: getattr(args, dest(spec), None) for spec in RUN if spec.flag}
    params = None
    if args.params_file:
        from ..parameters.params_file import controller_values, read_gains
        from ..robots import make_robot
        from ..robots.catalog import resolve_robot
        from ..robots.options import same_robot

        given = controller_values(args.params_file)
        for key, flag in FILE_SETTINGS.items():
            same = given.get(key, settings[key]) == settings[key] or (key == "robot" and same_robot(given[key],
                                                                                                   settings[key]))
            if not same:
                raise ConfigError(f"params file {args.params_file!r} sets {key}: {given[key]} but {flag} is "
                                  f"{settings[key]}: give the same, or leave one out")
        if not settings["rate"] and given.get("rate"):  # the rate the file's gains were chosen for
            settings["rate"] = positive_float(str(given["rate"]))
        params = read_gains(args.params_file, make_robot(resolve_robot(args.robot)).n, args.controller)
    return run_from_settings(settings, params=params, overrides=dict(args.gain or ()), model=args.model)


RUN_DEFAULTS = {**{dest(spec): spec.default or None for spec in RUN if spec.flag and spec.name not in REQUIRED},
                "no_enforce_limits": False, "gain": None, "model": None}
"""The run options montecarlo does not take (its runs are nominal, at the robot's rate), at the table's defaults."""


def file_controller(path: str, controllers: list[str]) -> str:
    """The law whose gains a params file holds (its ``type``), one of ``controllers``."""
    from ..parameters.params_file import controller_values

    controller = controller_values(path).get("type")
    if controller not in controllers:
        raise ConfigError(f"params file {path!r} holds gains for type {controller!r}; --controllers is "
                          f"{','.join(controllers)}: name it there (or add type: to the file)")
    return str(controller)


