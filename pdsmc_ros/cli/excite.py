"""``pdsmc excite``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..arguments import positive_float
from ..errors import ConfigError
from .options import count_at_most, positive_int, seed_value


def _harmonics(text: str) -> int:
    value = count_at_most(text, 20, "harmonics")
    if value < 2:
        raise argparse.ArgumentTypeError(f"expected at least 2 harmonics (rest at both ends needs two), got {text!r}")
    return value


def _share(text: str) -> float:
    value = positive_float(text)
    if value > 1.0:
        raise argparse.ArgumentTypeError(f"expected a share in (0, 1], got {text!r}")
    return value


def _non_negative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not np.isfinite(value) or value < 0.0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


def _positive_list(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected one number > 0 or one per joint, comma-separated, got {text!r}") \
            from None
    if not values or not all(np.isfinite(v) and v > 0.0 for v in values):
        raise argparse.ArgumentTypeError(f"expected one number > 0 or one per joint, comma-separated, got {text!r}")
    return values


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``excite`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser(
        "excite", help="an exciting trajectory for identification (Fourier series at rest at home at both ends, its "
        "base regressor's condition number minimised within the limits) as a FollowJointTrajectory goal file")
    p.add_argument("--robot", required=True,
                   help="the arm: an arm of example-robot-data (ur5, ...), a .urdf file, or serial_3r")
    p.add_argument("--out", required=True, help="directory for goal.yaml, excitation.yaml and excitation.png")
    p.add_argument("--period", type=positive_float, default=10.0, help="seconds of one period (default 10)")
    p.add_argument("--harmonics", type=_harmonics, default=5,
                   help="harmonics per joint (default 5: the motion's bandwidth is harmonics / period Hz)")
    p.add_argument("--periods", type=positive_int, default=4, help="periods in the goal (default 4)")
    p.add_argument("--excursion", type=_positive_list, default=[0.6], metavar="RAD[,RAD...]",
                   help="largest distance from home per joint (default 0.6 rad; no collision checking: keep it "
                   "where the arm moves freely)")
    p.add_argument("--share", type=_share, default=0.8,
                   help="share of the velocity, acceleration and effort limits used (default 0.8)")
    p.add_argument("--acceleration-limits", type=_positive_list, default=None, metavar="A[,A...]",
                   help="rad/s^2 per joint (default: each velocity limit reached in 0.5 s)")
    p.add_argument("--margin", type=_non_negative, default=0.05,
                   help="distance kept from position limits (default 0.05)")
    p.add_argument("--lead", type=positive_float, default=5.0,
                   help="seconds the goal takes from wherever the arm is to home before the excitation (default 5)")
    p.add_argument("--point-rate", type=positive_float, default=50.0,
                   help="goal points per second (default 50; the controller interpolates between them)")
    p.add_argument("--starts", type=positive_int, default=3, help="random starts of the search (default 3)")
    p.add_argument("--iterations", type=positive_int, default=40, help="L-BFGS iterations per start (default 40)")
    p.add_argument("--seed", type=seed_value, default=0, help="seed of the random starts (default 0)")
    commands["excite"] = run


def run(args: argparse.Namespace) -> int:
    import yaml

    from ..contours.goal_file import goal_data, write_goal
    from ..controller.joint_trajectory import MAX_POINTS
    from ..identification.base import base_parameters
    from ..identification.excitation import excitation_limits, optimise_excitation
    from ..identification.model import ArmDynamics, arm_of
    from ..identification.report import excitation_figure

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {str(out)!r} is a file: give a directory")
    dynamics = ArmDynamics(arm_of(args.robot))
    n = dynamics.n
    for flag, values in (("--excursion", args.excursion), ("--acceleration-limits", args.acceleration_limits)):
        if values is not None and len(values) not in (1, n):
            joints = ", ".join(dynamics.layout.joint_names)
            raise ConfigError(f"{flag} needs one value or {n} (one per joint: {joints}), "
                              f"got {len(values)}")
    duration = args.periods * args.period
    points = int(np.floor(duration * args.point_rate + 1e-9)) + 2
    if points > MAX_POINTS:
        raise ConfigError(f"the goal would hold {points} points ({args.periods} periods of {args.period:g} s at "
                          f"{args.point_rate:g} points/s); a controller takes at most {MAX_POINTS}: lower --point-rate "
                          "or "
                          "--periods")
    base = base_parameters(dynamics)
    limits = excitation_limits(dynamics, excursion=args.excursion, acceleration=args.acceleration_limits,
                               share=args.share, margin=args.margin)
    result = optimise_excitation(
        dynamics, base, limits, period=args.period, harmonics=args.harmonics, starts=args.starts,
        iterations=args.iterations, seed=args.seed,
        progress=lambda line: print(f"pdsmc excite: {line}", file=sys.stderr, flush=True))
    excitation = result.excitation
    t = np.arange(points - 1) / args.point_rate
    t = np.append(t[t < duration], duration)
    q, qd, qdd = excitation.sample(t)
    for end in (0, -1):  # at home at rest at both ends exactly (the series is, to rounding)
        q[end], qd[end], qdd[end] = excitation.home, 0.0, 0.0
    goal = goal_data(dynamics.layout.joint_names, t + args.lead, q, qd, qdd)
    description = {
        "robot": args.robot,
        "joint_names": list(dynamics.layout.joint_names),
        "home": excitation.home.tolist(),
        "period_s": excitation.period,
        "harmonics": excitation.harmonics,
        "periods": args.periods,
        "lead_s": args.lead,
        "bandwidth_hz": excitation.bandwidth,
        "a": excitation.a.tolist(),
        "b": excitation.b.tolist(),
        "condition_number": result.condition,
        "start_condition_number": result.start_condition,
        "base_parameters": base.size,
        "limits": {"lower": limits.lower.tolist(), "upper": limits.upper.tolist(),
                   "velocity": limits.velocity.tolist(), "acceleration": limits.acceleration.tolist(),
                   "effort": limits.effort.tolist()},
        "peak": {k: v.tolist() for k, v in result.peak.items()},
        "seconds": result.seconds,
        "seed": args.seed,
    }
    try:
        out.mkdir(parents=True, exist_ok=True)
        write_goal(out / "goal.yaml", goal,
                   f"FollowJointTrajectory goal: an excitation of {args.robot} for identification (pdsmc excite).\n"
                   f"{args.lead:g} s to home, then {args.periods} periods of {args.period:g} s at rest at home at both "
                   f"ends; condition number {result.condition:.4g}.\nSend it: pdsmc send-goal {out / 'goal.yaml'}")
        (out / "excitation.yaml").write_text(yaml.safe_dump(description, sort_keys=False, width=120))
        excitation_figure(dynamics, excitation, limits, out / "excitation.png")
    except OSError as exc:
        raise ConfigError(f"--out {str(out)!r}: cannot write it ({exc.strerror})") from None
    peak = result.peak
    print(f"{args.robot}: {excitation.harmonics} harmonics of {1.0 / excitation.period:.3g} Hz (bandwidth "
          f"{excitation.bandwidth:.3g} Hz), {args.periods} periods of {excitation.period:g} s after a {args.lead:g} s "
          "lead")
    print(f"condition number of the base regressor ({base.size} base parameters): {result.condition:.4g} (best random "
          f"start {result.start_condition:.4g}; {result.evaluations} evaluations in {result.seconds:.1f} s)")
    print("peak share of the arm's limits per joint: velocity "
          + " ".join(f"{v:.2f}" for v in peak["velocity_share"] * args.share)
          + ", acceleration " + " ".join(f"{v:.2f}" for v in peak["acceleration_share"] * args.share)
          + ", effort " + " ".join(f"{v:.2f}" for v in peak["effort_share"] * args.share)
          + "; largest excursion from home (rad) " + " ".join(f"{v:.3f}" for v in peak["excursion"]))
    print(f"wrote {out / 'goal.yaml'} ({len(goal['trajectory']['points'])} points), {out / 'excitation.yaml'}, "
          f"{out / 'excitation.png'}")
    return 0
