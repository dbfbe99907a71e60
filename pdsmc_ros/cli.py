"""The ``pdsmc`` command: simulate, reproduce the thesis, check gains.

Every error is one line on stderr naming the input and what is allowed, with
exit status 2 for bad input and 1 for a failure while running.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import __version__, rt_check
from .arguments import EXIT_USAGE, OneLineParser, gain_value
from .errors import ConfigError, InvalidInputError, PdsmcError

if TYPE_CHECKING:
    from .presets import RunSpec

EXIT_FAILURE = 1


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not np.isfinite(value) or value <= 0.0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


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


def _add_engine_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scheduler", default=None,
                   help="a Dask scheduler, tcp://HOST:PORT (default: a local cluster of --workers processes)")
    p.add_argument("--workers", type=worker_count, default=None, help="local cluster processes (default: cores)")


def _add_payload_reading(p: argparse.ArgumentParser) -> None:
    p.add_argument("--payload-reading", choices=("tip", "link_com"), default="tip",
                   help="where the payload scenario puts its load: tip (point mass at the end-effector, "
                   "default) or link_com (on the last link's centre of mass, the SMC's model rebuilt for it)")


def whole_number_from_zero(text: str) -> int:
    return whole_number(text, 0)


def _add_loop_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mode", choices=("realtime", "lockstep"), default="realtime",
                   help="the loop the gains must hold in: realtime (default: zero-order hold plus one period of "
                   "delay, as on a robot) or lockstep (zero-order hold, no delay)")
    p.add_argument("--delay-periods", type=whole_number_from_zero, default=0,
                   help="periods of delay beyond the mode's own (a driver's, a network's; default 0)")
    p.add_argument("--margin", type=positive_float, default=None,
                   help="required rate / lowest stable rate (default 2 in realtime, 1 in lockstep)")


def _add_run_arguments(p: argparse.ArgumentParser) -> None:
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
    _add_payload_reading(p)
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
    p.add_argument("--no-enforce-limits", action="store_true",
                   help="do not clamp the torque to the arm's effort limits (URDF <limit effort>, "
                   "config/robots.yaml); the clamp is on by default")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="pdsmc", description=__doc__)
    parser.add_argument("--version", action="version", version=f"pdsmc_ros {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)

    sim = sub.add_parser("simulate", help="simulate one run in-process and print its statistics")
    _add_run_arguments(sim)
    sim.add_argument("--json", action="store_true", help="print one JSON object")

    rep = sub.add_parser("reproduce", help="run the thesis matrix and write REPRODUCTION.md")
    rep.add_argument("--out", required=True, help="output directory")
    rep.add_argument("--workers", type=worker_count, default=None,
                     help="processes (default: cores; with --ros 1, as a composed run takes a core)")
    rep.add_argument("--scheduler", default=None, help="run the in-process matrix on a Dask cluster, tcp://HOST:PORT")
    rep.add_argument("--smc-reading", default="thesis_fit",
                     help="SMC model estimate for the SMC rows (default: thesis_fit)")
    _add_payload_reading(rep)
    rep.add_argument("--no-readings", action="store_true",
                     help="skip the comparison of SMC readings")
    rep.add_argument("--quiet", action="store_true", help="no progress lines")
    rep.add_argument("--ros", action="store_true",
                     help="run every case over DDS (lockstep, composed nodes) and analyse the bags")
    rep.add_argument("--bags", default="bags/reproduce", help="where --ros records its bags")
    rep.add_argument("--only", default=None,
                     help="glob over robot/contour/scenario/controller, e.g. 'serial_3r/circle/*/*'")

    ana = sub.add_parser("analyze", help="statistics of recorded bags, compared thesis-style")
    ana.add_argument("bags", nargs="+",
                     help="bags written by the recorder, or directories of bags (each inside, in name order)")
    ana.add_argument("--out", default=None, help="also write analysis.json and analysis.csv here")
    ana.add_argument("--json", action="store_true", help="print JSON instead of the table")
    ana.add_argument("--plots", action="store_true", help="write PNG figures into --out (default: analysis/)")

    swp = sub.add_parser("sweep", help="vary one PD-SMC parameter (Section 4.2.3, Table 4.15)")
    swp.add_argument("--param", required=True,
                     help="the PD-SMC gain varied, one its declaration and Table 4.15 give a range: kp, kd, ks, "
                     "lam (the thesis's lambda)")
    swp.add_argument("--robot", required=True, help="a registered robot: serial_3r, parallel_5r, ...")
    swp.add_argument("--contour", required=True)
    swp.add_argument("--out", default=None, help="write sweep_<param>.csv and .png here")
    swp.add_argument("--workers", type=worker_count, default=None)
    swp.add_argument("--scheduler", default=None, help="run the sweep on a Dask cluster, tcp://HOST:PORT")
    swp.add_argument("--values", type=value_list, default=None,
                     help="comma-separated values instead of the thesis's (e.g. 1,10,100)")

    chk = sub.add_parser("check-gains",
                         help="discrete-rate stability (with the loop's delay) and Eq. 3.19 of a run's gains")
    _add_run_arguments(chk)
    _add_loop_arguments(chk)

    mc = sub.add_parser("montecarlo", help="robustness: the controllers against a spread of plants (Dask)")
    mc.add_argument("--robot", required=True, help="serial_3r or parallel_5r (their link and motor parameters vary)")
    mc.add_argument("--contour", required=True)
    mc.add_argument("--controllers", type=name_list, default=["pd", "smc", "pdsmc"],
                    help="comma-separated control laws (default pd,smc,pdsmc)")
    mc.add_argument("--runs", type=run_count, required=True, help="plants drawn (each runs every controller)")
    mc.add_argument("--seed", type=seed_value, default=0, help="run i draws from default_rng([seed, i]) (default 0)")
    mc.add_argument("--params-file", default=None,
                    help="gains of the file's controller from a ROS 2 params file (pdsmc tune writes one)")
    mc.add_argument("--uncertainty", default=None,
                    help="YAML of parameter spreads (default: config/uncertainty.yaml)")
    _add_engine_arguments(mc)
    mc.add_argument("--out", required=True, help="directory for montecarlo.csv, .json and the plot")

    tun = sub.add_parser("tune", help="propose gains by the thesis's recipe (Section 4.2.3) and write a params file")
    tun.add_argument("--robot", required=True,
                     help="serial_3r, parallel_5r, an arm of example-robot-data (ur5, panda, ...) or a .urdf file")
    tun.add_argument("--contour", required=True)
    tun.add_argument("--controller", required=True, help="a registered control law: pd, smc, pdsmc, ...")
    tun.add_argument("--rate", type=positive_float, default=None, help="control rate in Hz (default: the robot's)")
    tun.add_argument("--rounds", type=positive_int, default=6, help="sweeps over kp, kd, ks, lam (default 6)")
    tun.add_argument("--out", default=None,
                     help="the params file to write (default: <robot>_<contour>_<controller>.yaml here)")
    tun.add_argument("--quiet", action="store_true", help="no line per candidate")
    tun.add_argument("--scheduler", default=None, help="run each gain's candidates on a Dask cluster, tcp://HOST:PORT")
    _add_loop_arguments(tun)
    rt_check.add_parser(sub, COMMANDS)  # pdsmc rt-check (pdsmc_ros/rt_check.py)
    return parser


FILE_SETTINGS = {"robot": "--robot", "contour": "--contour", "type": "--controller", "scenario": "--scenario"}
"""Run parameters of a params file that a flag also sets: they must agree."""


def _spec_from_args(args: argparse.Namespace) -> RunSpec:
    from .control import law
    from .presets import make_run, smc_reading

    params = None
    rate = args.rate
    if args.params_file:
        from .robots import ROBOTS
        from .robots.catalog import resolve_robot
        from .tuning import controller_parameters, read_params_file

        given = controller_parameters(args.params_file)
        flags = {"robot": args.robot, "contour": args.contour, "type": args.controller, "scenario": args.scenario}
        for key, flag in FILE_SETTINGS.items():
            same = given.get(key, flags[key]) == flags[key] or (key == "robot" and _same_robot(given[key], flags[key]))
            if not same:
                raise ConfigError(f"params file {args.params_file!r} sets {key}: {given[key]} but {flag} is "
                                  f"{flags[key]}: give the same, or leave one out")
        if rate is None and given.get("rate"):  # the rate the file's gains were chosen for
            rate = positive_float(str(given["rate"]))
        params = read_params_file(args.params_file, ROBOTS[resolve_robot(args.robot)].n, args.controller)
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
    )


_RUN_DEFAULTS = {"scenario": "nominal", "rate": None, "smc_reading": "literal", "ellipse_error": "nearest",
                 "waypoints": None, "segment_duration": 2.0, "payload_reading": "tip", "no_enforce_limits": False,
                 "gain": None}
"""The run arguments montecarlo does not take (its runs are nominal, at the robot's rate)."""


def _file_controller(path: str, controllers: list[str]) -> str:
    """The law whose gains a params file holds (its ``type``), one of ``controllers``."""
    from .tuning import controller_parameters

    controller = controller_parameters(path).get("type")
    if controller not in controllers:
        raise ConfigError(f"params file {path!r} holds gains for type {controller!r}; --controllers is "
                          f"{','.join(controllers)}: name it there (or add type: to the file)")
    return str(controller)


def _same_robot(a: object, b: str) -> bool:
    """Two spellings of one arm (a URDF file by two paths, a name and its registration)."""
    from .robots.catalog import resolve_robot

    try:
        return resolve_robot(str(a)) == resolve_robot(b)
    except PdsmcError:
        return False


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
"""The scores' lines of :func:`format_metrics` (pdsmc_ros/scores.py, docs/SCORES.md)."""


def score_lines(metrics: dict) -> list[str]:
    """The scores per joint and for the run (``run``), when the run has them."""
    run = metrics.get("run_scores")
    if not run:
        return []
    return [f"{label.format(run['cutoff_hz']):23s}: " + "  ".join(f"{v:.4g}" for v in metrics[key])
            + f"  run {run[key]:.4g}" for key, label in SCORE_LABELS]


def cmd_simulate(args: argparse.Namespace) -> int:
    from .sim import simulate

    spec = _spec_from_args(args)
    if args.no_enforce_limits:
        from dataclasses import replace

        spec = replace(spec, enforce_limits=False)
    result = simulate(spec)
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


def cmd_reproduce(args: argparse.Namespace) -> int:
    from .thesis.cells import summarize
    from .thesis.report import write_report
    from .thesis.reproduce import run_reproduction

    def progress(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    rep = run_reproduction(
        smc=args.smc_reading,
        workers=args.workers,
        readings=not args.no_readings and not args.only,
        progress=None if args.quiet else progress,
        only=args.only,
        ros_bags=Path(args.bags) if args.ros else None,
        payload_reading=args.payload_reading,
        scheduler=args.scheduler,
    )
    paths = write_report(rep, Path(args.out))
    from .control import law

    main = summarize(c for c in rep.cells if not law(c.controller).model_based)
    smc = summarize(c for c in rep.cells if law(c.controller).model_based)
    print(
        f"{len(rep.results)} runs in {rep.wall_s:.1f} s; PD/PD-SMC cells: median |dev| "
        f"{100 * main['median_abs_dev']:.2f} %, {100 * main['within_5pct']:.1f} % within 5 %; "
        f"SMC cells ({rep.smc_reading}): median |dev| {100 * smc['median_abs_dev']:.2f} %, "
        f"{100 * smc['within_5pct']:.1f} % within 5 %"
    )
    print(f"wrote {paths['markdown']}, {paths['csv']}, {paths['json']}")
    return 0


def cmd_check_gains(args: argparse.Namespace) -> int:
    from .control import law
    from .control.stability import THEOREM_LAWS, check_gains, describe_loop

    spec = _spec_from_args(args)
    print(f"{spec.robot} / {spec.contour} / {spec.controller} / {spec.scenario}: gains "
          + ", ".join(f"{k}={list(spec.gains[k])}" for k in law(spec.controller).gain_names))
    result = check_gains(spec, mode=args.mode, delay_periods=args.delay_periods, margin=args.margin)
    if result.conditions:
        print("Lyapunov conditions of Eq. 3.19 along the desired motion (worst instant):")
    else:
        print(f"Eq. 3.19 is the theorem of the {', '.join(THEOREM_LAWS)} law: no conditions of it for "
              f"{spec.controller}; the discrete-rate condition only")
    for c in result.conditions:
        margin = "inf" if c.margin == float("inf") else f"x{c.margin:.3g}"
        print(f"  {'holds' if c.holds else 'FAILS':5s}  {c.name:52s} {c.lhs:12.5g} > {c.rhs:<12.5g} margin {margin}")
    check = result.rate
    if not np.isfinite(check.lowest_stable_rate):
        print(f"discrete-rate condition: not checked ({spec.controller} has no linear gains)")
    else:
        print(
            f"discrete-rate condition at {spec.rate:g} Hz {'holds' if check.passes else 'FAILS'} in "
            f"{describe_loop(check)}: largest pole radius {check.spectral_radius:.4f} "
            f"(joint {check.worst_joint}); lowest stable rate {check.lowest_stable_rate:,.0f} Hz, margin "
            f"x{check.margin:.2f} (x{check.required_margin:g} required, --margin)"
        )
    return 0 if result.passes else EXIT_FAILURE


def cmd_analyze(args: argparse.Namespace) -> int:
    from .thesis.analysis import analyze_bag, comparison_table, find_bags, write_outputs

    paths, skipped = find_bags(args.bags)
    for line in skipped:
        print(f"pdsmc analyze: {line}", file=sys.stderr)
    if not paths:
        raise InvalidInputError(f"no bag among {', '.join(map(repr, args.bags))} (a bag is a directory "
                                "written by the recorder, or a directory of such bags)")
    bags = [analyze_bag(path) for path in paths]
    if args.plots:
        from .bag.reader import run_samples
        from .thesis.plots import plot_comparison, plot_controllers, plot_run

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
        print(json.dumps([b.as_dict() for b in bags]))
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


def cmd_sweep(args: argparse.Namespace) -> int:
    from .thesis.sweep import run_sweep

    def progress(done: int, total: int, _res: object) -> None:
        print(f"[{done}/{total}]", end="\r", file=sys.stderr, flush=True)

    param, points = run_sweep(args.param, args.robot, args.contour, values=args.values,
                              workers=args.workers, progress=progress, scheduler=args.scheduler)
    label = param
    print(f"PD-SMC, {args.robot} / {args.contour}: {label} varied, others at Kp=5000, Kd=1000, Ks=5, "
          "lambda=10, phi=0.5 (Section 4.2.3)")
    print(f"{label:>8s} {'rate (Hz)':>10s} {'mean (m)':>11s} {'S.D. (m)':>11s} {'max (m)':>11s} {'within':>8s}")
    for p in points:
        flag = "  diverged" if p.diverged else ""
        print(f"{p.value:8g} {p.rate:10g} {p.contour_mean:11.4e} {p.contour_sd:11.4e} {p.contour_max:11.4e} "
              f"{p.within_pct:7.2f}%{flag}")
    if args.out:
        import csv

        from .thesis.plots import plot_sweep

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        with (out / f"sweep_{label}.csv").open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow([label, "rate_hz", "contour_mean", "contour_sd", "contour_max", "within_pct", "diverged"])
            for p in points:
                writer.writerow(
                    [p.value, p.rate, p.contour_mean, p.contour_sd, p.contour_max, p.within_pct, p.diverged]
                )
        ok = [p for p in points if not p.diverged]
        plot_sweep(label, np.array([p.value for p in ok]), np.array([p.contour_mean for p in ok]),
                   np.array([p.contour_sd for p in ok]), np.array([p.contour_max for p in ok]),
                   out / f"sweep_{label}.png", f"PD-SMC {args.robot}/{args.contour}: {label}")
        print(f"wrote {out}/sweep_{label}.csv and .png", file=sys.stderr)
    return 0


def cmd_tune(args: argparse.Namespace) -> int:
    from .control import law
    from .tuning import Candidate, Requirement, tune, write_params_file

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
    requirement = Requirement(args.mode, args.delay_periods, args.margin)
    result = tune(args.robot, args.contour, args.controller, rate=args.rate, rounds=args.rounds,
                  progress=None if args.quiet else progress, scheduler=args.scheduler, requirement=requirement)
    spec = result.spec
    try:
        write_params_file(out, result.best.gains, controller=spec.controller, robot=spec.robot,
                          contour=spec.contour, rate=spec.rate, requirement=requirement)
    except OSError as exc:
        raise ConfigError(f"--out {str(out)!r}: cannot write it ({exc.strerror}); the best gains: "
                          f"{result.best.gains.as_dict()}") from None
    tried = len(result.tried)
    refused = sum(not c.ok for c in result.tried)
    print(f"{spec.robot}/{spec.contour}/{spec.controller} at {spec.rate:g} Hz: contour error mean "
          f"{result.best.contour_mean:.4e} m (start {result.start.contour_mean:.4e} m) after {tried} runs "
          f"({refused} refused); wrote {out}")
    return 0


def cmd_montecarlo(args: argparse.Namespace) -> int:
    from .control import law
    from .control.stability import check_rate
    from .engine import Progress, dask_client, run_tasks
    from .montecarlo import base_specs, load_uncertainty, plot_distribution, run_sample, summarize, write_outputs

    for controller in args.controllers:
        law(controller)
    spreads = load_uncertainty(args.uncertainty)
    specs = base_specs(args.robot, args.contour, args.controllers)
    if args.params_file:  # the file's controller runs the file's gains (scaled as simulate scales them)
        specs = [_spec_from_args(argparse.Namespace(**{**_RUN_DEFAULTS, **vars(args), "controller": spec.controller}))
                 if spec.controller == _file_controller(args.params_file, args.controllers) else spec
                 for spec in specs]
    for spec in specs:  # the nominal gains must be stable at the rate; a drawn plant may still diverge
        check_rate(spec, spec.reference())
    out = Path(args.out)
    bound = specs[0].bound
    meta = {"robot": args.robot, "contour": args.contour, "controllers": list(args.controllers), "runs": args.runs,
            "seed": args.seed, "uncertainty": {k: vars(v) for k, v in spreads.items()}, "contour_bound_m": bound}
    rows: list[Any] = []
    done = 0
    progress = Progress(args.runs, "montecarlo")
    interrupted = False
    with dask_client(args.scheduler, args.workers) as client:
        try:
            for _, result in run_tasks(client, run_sample, [(i, args.seed, specs, spreads) for i in range(args.runs)]):
                rows += result
                done += 1
                progress.step()
        except KeyboardInterrupt:
            interrupted = True
    meta["runs_done"] = done
    summary = summarize(rows, args.controllers, bound)
    written = write_outputs(rows, summary, meta, out)
    if rows:
        written.append(plot_distribution(rows, args.controllers, bound, out / "montecarlo.png",
                                         f"{args.robot}/{args.contour}: {done} plants"))
    for controller in args.controllers:
        entry = summary[controller]
        if "contour_mean_mean" in entry:
            print(f"{controller:6s} contour mean over {entry['runs']} runs: mean {entry['contour_mean_mean']:.4e}  "
                  f"p5 {entry['contour_mean_p5']:.4e}  p50 {entry['contour_mean_p50']:.4e}  "
                  f"p95 {entry['contour_mean_p95']:.4e}  worst {entry['contour_mean_worst']:.4e} m; "
                  f"{100 * entry['share_within_bound']:.1f} % within {bound:g} m; {entry['failed']} failed")
    print(f"wrote {', '.join(str(p) for p in written)}", file=sys.stderr)
    if interrupted:
        print(f"pdsmc montecarlo: interrupted: the table is partial ({done} of {args.runs} runs)", file=sys.stderr)
        return 130
    return 0


COMMANDS = {
    "montecarlo": cmd_montecarlo,
    "tune": cmd_tune,
    "sweep": cmd_sweep,
    "simulate": cmd_simulate,
    "reproduce": cmd_reproduce,
    "analyze": cmd_analyze,
    "check-gains": cmd_check_gains,
}


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except InvalidInputError as exc:
        print(f"pdsmc {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except PdsmcError as exc:
        print(f"pdsmc {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_FAILURE
    except KeyboardInterrupt:
        print(f"pdsmc {args.command}: interrupted", file=sys.stderr)
        return 130


def analyze_main(argv: Sequence[str] | None = None) -> int:
    """``ros2 run pdsmc_ros analyze BAG ...``: the same as ``pdsmc analyze``."""
    return main(["analyze", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
