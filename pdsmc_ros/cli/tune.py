"""``pdsmc tune``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..errors import ConfigError
from .options import (
    add_loop_arguments,
    add_model_argument,
    positive_float,
    positive_int,
)


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``tune`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser("tune", help="propose gains by the thesis's recipe (Section 4.2.3) and write a params file")
    p.add_argument("--robot", required=True,
                   help="serial_3r, parallel_5r, an arm of example-robot-data (ur5, panda, ...) or a .urdf file")
    p.add_argument("--contour", required=True)
    p.add_argument("--controller", required=True, help="a registered control law: pd, smc, pdsmc, ...")
    p.add_argument("--rate", type=positive_float, default=None, help="control rate in Hz (default: the robot's)")
    p.add_argument("--rounds", type=positive_int, default=6, help="sweeps over kp, kd, ks, lam (default 6)")
    p.add_argument("--out", default=None,
                   help="the params file to write (default: <robot>_<contour>_<controller>.yaml here)")
    p.add_argument("--quiet", action="store_true", help="no line per candidate")
    p.add_argument("--scheduler", default=None, help="run each gain's candidates on a Dask cluster, tcp://HOST:PORT")
    add_model_argument(p)
    add_loop_arguments(p)
    commands["tune"] = run


def run(args: argparse.Namespace) -> int:
    from ..control import law
    from ..experiments.tuning import Candidate, Requirement, tune
    from ..parameters.params_file import write_params_file

    def progress(candidate: Candidate) -> None:
        error = "-" if candidate.contour_mean is None else f"{candidate.contour_mean:.4e} m"
        gains = ", ".join(f"{k}={[float(f'{x:.4g}') for x in v]}" for k, v in candidate.gains.as_dict().items()
                          if k in law(args.controller).gain_names)
        print(f"contour mean {error:>14s}  {candidate.verdict:.90s}  {gains}", file=sys.stderr, flush=True)

    out = Path(args.out or f"{Path(args.robot).stem}_{args.contour}_{args.controller}.yaml")
    if out.is_dir():
        raise ConfigError(f"--out {str(out)!r} is a directory: give the params file's path")
    try:  # before the search, not after it
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--out {str(out)!r}: cannot create {str(out.parent)!r} ({exc.strerror})") from None
    requirement = Requirement(args.mode, args.delay_periods, args.margin, args.realism)
    result = tune(args.robot, args.contour, args.controller, rate=args.rate, rounds=args.rounds,
                  progress=None if args.quiet else progress, scheduler=args.scheduler, requirement=requirement,
                  model=args.model)
    spec = result.spec
    try:
        write_params_file(out, result.best.gains, controller=spec.controller, robot=spec.robot,
                          contour=spec.contour, rate=spec.rate, accepted_by=requirement.command())
    except OSError as exc:
        raise ConfigError(f"--out {str(out)!r}: cannot write it ({exc.strerror}); the best gains: "
                          f"{result.best.gains.as_dict()}") from None
    tried = len(result.tried)
    refused = sum(not c.ok for c in result.tried)
    print(f"{spec.robot}/{spec.contour}/{spec.controller} at {spec.rate:g} Hz: contour error mean "
          f"{result.best.contour_mean:.4e} m (start {result.start.contour_mean:.4e} m) after {tried} runs "
          f"({refused} refused); wrote {out}")
    return 0
