"""``pdsmc analyze``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ..arguments import EXIT_FAILURE
from ..errors import InvalidInputError


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``analyze`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser("analyze", help="statistics of recorded bags, compared thesis-style")
    p.add_argument("bags", nargs="+",
                   help="bags written by the recorder, or directories of bags (each inside, in name order); a bag "
                   "of a graph the recorder did not start (a real arm's run) is analysed per action goal")
    p.add_argument("--out", default=None, help="also write analysis.json and analysis.csv here")
    p.add_argument("--json", action="store_true", help="print JSON instead of the table")
    p.add_argument("--plots", action="store_true", help="write PNG figures into --out (default: analysis/)")
    p.add_argument("--robot", default=None,
                   help="a recorded graph: the arm whose velocity and effort limits apply (default: the bag's "
                   "/robot_description)")
    p.add_argument("--settle-band", type=float, default=None, metavar="RAD",
                   help="a recorded graph: a goal has settled once every joint stays this close to its last "
                   "desired position (default 0.01 rad)")
    commands["analyze"] = run


def run(args: argparse.Namespace) -> int:
    from ..bag.graph import is_graph_bag
    from ..experiments.analysis import find_bags

    paths, skipped = find_bags(args.bags)
    for line in skipped:
        print(f"pdsmc analyze: {line}", file=sys.stderr)
    if not paths:
        raise InvalidInputError(f"no bag among {', '.join(map(repr, args.bags))} (a bag is a directory "
                                "written by the recorder, or a directory of such bags)")
    if args.settle_band is not None and not args.settle_band > 0:
        raise InvalidInputError(f"--settle-band must be a number of radians > 0, got {args.settle_band!r}")
    graphs = [path for path in paths if is_graph_bag(path)]
    pipeline = [path for path in paths if path not in graphs]
    reports: list[Any] = []  # --json: one list of both kinds
    code = run_pipeline(args, pipeline, reports) if pipeline else 0
    if graphs:
        code = max(code, run_graphs(args, graphs, reports, after_table=bool(pipeline)))
    if args.json:
        print(json.dumps(reports))
    return code


def run_graphs(args: argparse.Namespace, paths: list[Path], reports: list[Any], *, after_table: bool) -> int:
    """Recorded graphs (a real arm's runs): one table per bag, a column per goal."""
    from ..experiments.analysis import analyze_graph_bag, goal_table, write_graph_outputs
    from ..experiments.goal_figures import DEFAULT_SETTLE_BAND

    band = DEFAULT_SETTLE_BAND if args.settle_band is None else args.settle_band
    bags = [analyze_graph_bag(path, robot=args.robot, settle_band=band) for path in paths]
    if args.plots:
        print("pdsmc analyze: --plots draws the project's own runs; a recorded graph has its table only",
              file=sys.stderr)
    if args.json:
        reports += [b.as_dict() for b in bags]
    else:
        for i, b in enumerate(bags):
            if i or after_table:
                print()
            print(goal_table(b))
    if args.out:
        for path in write_graph_outputs(bags, Path(args.out)):
            print(f"wrote {path}", file=sys.stderr)
    for b in bags:
        if not b.goals:
            print(f"pdsmc analyze: {b.path}: no action goal in it (none was sent, or the action's status was not "
                  "recorded: recorder actions:=[...])", file=sys.stderr)
        if b.diverged:
            print(f"pdsmc analyze: {b.path}: the run {b.diverged}", file=sys.stderr)
    return EXIT_FAILURE if any(b.diverged for b in bags) else 0


def run_pipeline(args: argparse.Namespace, paths: list[Path], reports: list[Any]) -> int:
    """Bags of the project's own pipeline: the thesis-style comparison."""
    from ..experiments.analysis import analyze_bag, comparison_table, write_outputs

    bags = [analyze_bag(path) for path in paths]
    if args.plots:
        from ..bag.reader import run_samples
        from ..experiments.plots import plot_comparison, plot_controllers, plot_run

        out = Path(args.out or "analysis")
        written = []
        groups: dict[tuple[str, str, str], list[Any]] = {}
        for b in bags:
            samples = run_samples(b.run)
            written += plot_run(samples, b.run.spec.robot, b.path.name, out)
            spec = b.run.spec
            if not b.diverged:  # a diverged run would set the comparison figures' scales
                groups.setdefault((spec.robot, spec.contour, spec.scenario), []).append(
                    (spec.controller, samples, spec))
        for (robot, contour, scenario), runs in groups.items():
            # the thesis's comparison figures: every controller of one robot, contour and scenario together
            name = f"{Path(robot).stem}_{contour}" + ("" if scenario == "nominal" else f"_{scenario}")
            written += plot_controllers([(c, s) for c, s, _ in runs], robot, name, runs[0][2].bound, out)
        compared = [b for b in bags if not b.diverged]
        written.append(plot_comparison([b.label for b in compared], [b.metrics.contour_mean for b in compared],
                                       out / "contour_mean_comparison.png", "mean contour error"))
        print(f"wrote {len(written)} figures into {out}/", file=sys.stderr)
    if args.json:
        reports += [b.as_dict() for b in bags]
    else:
        print(comparison_table(bags))
    if args.out:
        for path in write_outputs(bags, Path(args.out)):
            print(f"wrote {path}", file=sys.stderr)
    bad = [b for b in bags if b.run.truncated or (not b.run.complete and b.run.description.get("mode") != "realtime")]
    for b in bags:
        if b in bad:
            what = "truncated (recorder stopped without closing it)" if b.run.truncated else "incomplete"
            print(f"pdsmc analyze: {b.path}: {what}: statistics of the {b.metrics.samples} readable samples "
                  f"only; missing steps {b.run.missing}", file=sys.stderr)
    for b in bags:
        if b.run.description_from_recorder:
            print(f"pdsmc analyze: {b.path}: the controller's run description never reached the "
                  "recorder; the run is named by the recorder's own parameters (gains may differ)",
                  file=sys.stderr)
        if b.run.plant_torque_steps:
            print(f"pdsmc analyze: {b.path}: for {b.run.plant_torque_steps} steps the plant applied a "
                  "torque other than a recorded command (safe mode, see /diagnostics); the statistics "
                  "use the torque applied", file=sys.stderr)
    for b in bags:
        if b.diverged:
            print(f"pdsmc analyze: {b.path}: the run {b.diverged}: marked diverged, left out of the "
                  "comparisons and of the comparison figures' scales", file=sys.stderr)
    if bad or any(b.diverged for b in bags):
        return EXIT_FAILURE
    return 0
