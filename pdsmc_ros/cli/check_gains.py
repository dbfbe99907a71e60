"""``pdsmc check-gains``."""

from __future__ import annotations

import argparse

import numpy as np

from ..arguments import EXIT_FAILURE
from .options import (
    add_loop_arguments,
    add_run_arguments,
    spec_from_args,
)


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``check-gains`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser("check-gains",
                       help="discrete-rate stability (with the loop's delay) and Eq. 3.19 of a run's gains")
    add_run_arguments(p)
    add_loop_arguments(p)
    commands["check-gains"] = run


def run(args: argparse.Namespace) -> int:
    from ..control import law
    from ..control.stability import THEOREM_LAWS, check_gains, describe_loop, tolerated_delay
    from ..experiments.tuning import Requirement

    spec = spec_from_args(args)
    delay, filter_hz, viscous = Requirement(args.mode, args.delay_periods, args.margin, args.realism).loop_terms(
        spec.robot, spec.rate)
    print(f"{spec.robot} / {spec.contour} / {spec.controller} / {spec.scenario}: gains "
          + ", ".join(f"{k}={list(spec.gains[k])}" for k in law(spec.controller).gain_names))
    result = check_gains(spec, mode=args.mode, delay_periods=delay, margin=args.margin, filter_hz=filter_hz,
                         friction_viscous=viscous)
    if result.conditions:
        print("Lyapunov conditions of Eq. 3.19 along the desired motion (worst instant):")
    else:
        print(f"Eq. 3.19 is the theorem of the {', '.join(THEOREM_LAWS)} law: no conditions of it for "
              f"{spec.controller}; the discrete-rate condition only")
    for c in result.conditions:
        margin = "inf" if c.margin == float("inf") else f"x{c.margin:.3g}"
        print(f"  {'holds' if c.holds else 'FAILS':5s}  {c.name:52s} {c.lhs:12.5g} > {c.rhs:<12.5g} margin {margin}")
    check = result.rate
    if check.plant is not None:
        if check.plant.holds:
            largest = f"joint {check.plant.joint!r} the largest" if check.plant.figure > 0.0 else "no joint damped"
            print(f"plant step at {spec.rate:g} Hz holds: damping/inertia x period {check.plant.figure:.3g} <= "
                  f"{check.plant.limit:.3g} ({largest})")
        else:
            print(f"plant step at {spec.rate:g} Hz FAILS: {check.plant.problem()}")
    if not np.isfinite(check.lowest_stable_rate):
        print(f"discrete-rate condition: not checked ({spec.controller} has no linear gains)")
    else:
        print(
            f"discrete-rate condition at {spec.rate:g} Hz {'holds' if check.passes else 'FAILS'} in "
            f"{describe_loop(check)}: largest pole radius {check.spectral_radius:.4f} "
            f"({check.worst_joint_label}); lowest stable rate {check.lowest_stable_rate:,.0f} Hz, margin "
            f"x{check.margin:.2f} (x{check.required_margin:g} required, --margin)"
        )
        if check.stable:
            most = tolerated_delay(spec, spec.reference(), filter_hz=filter_hz, friction_viscous=viscous)
            print(f"stable at {spec.rate:g} Hz with a constant delay of up to {most} periods "
                  f"({most / spec.rate * 1e3:.3g} ms): what a loop's stalls may reach at most")
    return 0 if result.passes else EXIT_FAILURE
