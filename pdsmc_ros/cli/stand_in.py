"""The flags that run a command's law against the MuJoCo stand-in: ``--plant mujoco``, ``--realism``
and one flag per nuisance, made from the ``mujoco_driver``'s parameters (the one table,
:func:`pdsmc_ros.parameters.realism_parameters`): ``-p friction_coulomb:=[1.0, 0.5]`` on the node is
``--friction-coulomb 1.0,0.5`` here, checked by the same declarations."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from ..errors import ConfigError

if TYPE_CHECKING:
    from ..sim.mujoco_lockstep import StandIn

PLANTS = ("model", "mujoco")
"""``model``: the in-process plant (the arm's own dynamics, Eq. 4.1); ``mujoco``: the MuJoCo stand-in
in lockstep, with its nuisances."""


def _values(kind: str) -> Any:
    """An argparse type: comma-separated values of ``kind`` (``double``, ``int``) or one ``bool``."""

    def parse(text: str) -> Any:
        if kind == "bool":
            if text.lower() not in ("true", "false"):
                raise argparse.ArgumentTypeError(f"expected true or false, got {text!r}")
            return text.lower() == "true"
        try:
            values = [(int if kind == "int" else float)(v) for v in text.split(",") if v.strip()]
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated {'whole ' if kind == 'int' else ''}numbers, "
                                             f"got {text!r}") from None
        if not values:
            raise argparse.ArgumentTypeError(f"expected one value or more, got {text!r}")
        return values

    return parse


def add_stand_in_arguments(p: argparse.ArgumentParser, *, seed: bool = True) -> None:
    """``--plant``, ``--realism``, ``--substeps``, ``--seed`` (unless the command has its own) and a flag
    per nuisance."""
    from ..parameters import realism_parameters

    group = p.add_argument_group("the MuJoCo stand-in (--plant mujoco; docs/how-to/mujoco.md)")
    group.add_argument("--plant", choices=PLANTS, default="model",
                       help="model (default): the arm's own dynamics; mujoco: the law against the MuJoCo stand-in in "
                       "lockstep, with its nuisances (--realism and the flags below)")
    group.add_argument("--substeps", type=int, default=1, help="MuJoCo steps a control period (default 1: RK4 at the "
                       "period, the in-process plant's step)")
    for spec in realism_parameters():
        if spec.name == "seed" and not seed:
            continue
        flag = "--" + spec.name.replace("_", "-")
        if spec.type == "string":
            group.add_argument(flag, choices=spec.allowed_choices(), default=spec.default, help=spec.description)
        elif spec.is_array:
            group.add_argument(flag, type=_values(spec.element), default=None, metavar="V[,V...]",
                               help=spec.description)
        elif spec.type == "bool":
            group.add_argument(flag, type=_values("bool"), default=spec.default, metavar="true|false",
                               help=spec.description)
        else:
            group.add_argument(flag, type=int if spec.type == "int" else float, default=spec.default,
                               metavar="N" if spec.type == "int" else "X", help=spec.description)


def stand_in_from_args(args: argparse.Namespace, *, seed: int | None = None) -> StandIn | None:
    """The stand-in the flags name, or None for ``--plant model`` (then no nuisance flag may be given).

    Raises
    ------
    ConfigError
        A nuisance flag without ``--plant mujoco``; a bad ``--substeps``.
    """
    from ..parameters import realism_parameters
    from ..sim.mujoco_lockstep import StandIn
    from ..sim.realism import SETTINGS

    names = [spec.name for spec in realism_parameters() if spec.name not in SETTINGS]
    given = {name: getattr(args, name) for name in names if getattr(args, name, None) is not None}
    if args.plant != "mujoco":
        extra = [f"--{name.replace('_', '-')}" for name in given]
        if args.realism != "ideal":
            extra.insert(0, "--realism")
        if extra:
            raise ConfigError(f"{extra[0]} is for the MuJoCo stand-in: give --plant mujoco with it")
        return None
    if args.substeps < 1:
        raise ConfigError(f"--substeps must be >= 1, got {args.substeps}")
    chosen = seed if seed is not None else getattr(args, "seed", 0)
    return StandIn(preset=args.realism, given=given, seed=int(chosen or 0), substeps=args.substeps)


def describe_plant(stand_in: StandIn | None, robot: str, rate: float) -> dict[str, Any]:
    """What a run's plant was, as plain data (the JSON outputs): ``model``, or the stand-in with its
    nuisances resolved for the arm (:class:`~pdsmc_ros.sim.realism.RealismError` if one is refused)."""
    if stand_in is None:
        return {"plant": "model"}
    _, realism, _ = stand_in.resolve(robot, rate)
    return {"plant": "mujoco", "substeps": stand_in.substeps, **realism.describe(), "summary": realism.summary()}
