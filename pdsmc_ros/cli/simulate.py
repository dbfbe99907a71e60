"""``pdsmc simulate``."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from ..arguments import EXIT_FAILURE
from .options import (
    add_run_arguments,
    spec_from_args,
)


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``simulate`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser("simulate", help="simulate one run in-process and print its statistics")
    add_run_arguments(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    commands["simulate"] = run


def run(args: argparse.Namespace) -> int:
    from ..sim import simulate

    spec = spec_from_args(args)
    if args.no_enforce_limits:
        from dataclasses import replace

        spec = replace(spec, enforce_limits=False)
    result = simulate(spec, keep_samples=False)  # prints statistics only: memory need not grow with the run
    for line in result.limit_warnings:
        print(f"pdsmc simulate: warning: {line}", file=sys.stderr)
    saturated = result.metrics.saturated_periods
    if any(saturated):
        limits = spec.robot_model().effort_limits
        print("pdsmc simulate: torque clamped to the effort limits in " + ", ".join(
            f"{count} periods of joint {i + 1} (|tau| <= {limits[i]:.4g} N m)" for i, count in enumerate(saturated)
            if count) + " (--no-enforce-limits to opt out)", file=sys.stderr)
    if args.json:
        print(json.dumps(result.as_dict()))
    if result.diverged:
        print(f"pdsmc simulate: error: the run {result.diverged}; stopped there", file=sys.stderr)
        return EXIT_FAILURE
    if args.json:
        return 0
    d = spec.describe()
    print(
        f"{spec.robot} / {spec.contour} / {spec.controller} / {spec.scenario}"
        f"{f' ({spec.payload:g} kg, {spec.payload_reading})' if spec.payload > 0.0 else ''}: "
        f"{d['duration_s']:g} s at {spec.rate:g} Hz control, statistics at {spec.sample_rate:g} Hz "
        f"({result.metrics.samples} samples), {result.wall_s:.2f} s wall"
    )
    print(format_metrics(result.metrics.as_dict(), spec.gains.n))
    return 0


def format_metrics(metrics: dict[str, Any], robot_n: int) -> str:
    """Human-readable statistics of one run."""
    axes = range(robot_n)
    lines = [
        "axial error mean (rad): " + "  ".join(f"{metrics['axial_mean'][i]:.4e}" for i in axes),
        "axial error SD   (rad): " + "  ".join(f"{metrics['axial_sd'][i]:.4e}" for i in axes),
        "task error mean    (m): x {x:.4e}  y {y:.4e}  total {total:.4e}".format(**metrics["task_mean"]),
        "task error SD      (m): x {x:.4e}  y {y:.4e}  total {total:.4e}".format(**metrics["task_sd"]),
        (f"contour error      (m): mean {metrics['contour_mean']:.4e}  SD {metrics['contour_sd']:.4e}"
        f"  within {metrics['contour_bound']:g} m: {metrics['contour_within_pct']:.2f} %"),
        "max |torque|     (N m): " + "  ".join(f"{metrics['max_torque'][i]:.4g}" for i in axes),
    ]
    if metrics.get("saturated_periods"):
        lines.append("saturated periods      : " + "  ".join(str(c) for c in metrics["saturated_periods"]))
    lines += score_lines(metrics)
    return "\n".join(lines)


SCORE_LABELS = (("error_rms", "RMS error        (rad)"), ("error_itae", "ITAE       (rad s^2)"),
                ("torque_tv_rate", "torque TV/s   (N m/s)"), ("torque_hf_share", "torque power > {:g} Hz"),
                ("control_energy", "energy   (N^2 m^2 s)"), ("torque_rate_peak", "peak dtau/dt  (N m/s)"))
"""The scores' lines of :func:`format_metrics` (pdsmc_ros/metrics/scores.py, docs/SCORES.md)."""


def score_lines(metrics: dict) -> list[str]:
    """The scores per joint and for the run (``run``), when the run has them."""
    run = metrics.get("run_scores")
    if not run:
        return []
    return [f"{label.format(run['cutoff_hz']):23s}: " + "  ".join(f"{v:.4g}" for v in metrics[key])
            + f"  run {run[key]:.4g}" for key, label in SCORE_LABELS]
