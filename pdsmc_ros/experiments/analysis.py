"""Offline analysis of recorded runs: thesis-style tables comparing bags.

Every statistic comes from :mod:`pdsmc_ros.metrics.statistics` through
:func:`pdsmc_ros.bag.reader.run_metrics`, the same code as the in-process simulator.
A bag of a graph the recorder did not start (a real arm's run: :mod:`pdsmc_ros.bag.graph`)
is analysed per action goal (:mod:`.goals`, :func:`analyze_graph_bag`).
"""

from __future__ import annotations

import csv
import dataclasses
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..bag.graph import GraphRun, read_graph_run
from ..bag.loop_statistics import format_loop_statistics, loop_report_lines
from ..bag.reader import RecordedRun, read_run, run_metrics
from ..control import LAWS
from ..errors import BagError, ConfigError, InvalidInputError
from ..metrics.scores import DEFAULT_CUTOFF_HZ
from ..metrics.statistics import Metrics
from ..sim.divergence import DivergenceCheck
from .goal_figures import DEFAULT_SETTLE_BAND, GoalFigures, late_periods, nominal_period, run_goal_figures


def is_bag(path: Path) -> bool:
    """A recorded bag: an ``.mcap`` file, or a directory with one or a ``metadata.yaml`` (rosbag2)."""
    if path.is_dir():
        return (path / "metadata.yaml").is_file() or any(path.glob("*.mcap"))
    return path.suffix == ".mcap" and path.is_file()


def find_bags(paths: Sequence[str | Path]) -> tuple[list[Path], list[str]]:
    """The bags named by ``paths``, and one line for each path that names none.

    A bag stands for itself; a directory that is not a bag stands for the bags
    directly inside it, in name order (``bags/demo-.../`` holds one run per
    controller). Anything else -- a shell glob's ``*.logs`` directory, a stray
    file -- is skipped, and said so.

    Raises
    ------
    InvalidInputError
        If a path does not exist (a typing mistake, not a glob's by-product).
    """
    bags: list[Path] = []
    skipped: list[str] = []
    for name in paths:
        path = Path(name)
        if not path.exists():
            raise InvalidInputError(f"bag {str(path)!r} does not exist")
        if is_bag(path):
            bags.append(path)
            continue
        inside = sorted(p for p in path.iterdir() if is_bag(p)) if path.is_dir() else []
        if inside:
            bags += inside
        else:
            what = "a directory with no .mcap file and no bag inside" if path.is_dir() else "not an .mcap file"
            skipped.append(f"skipping {str(path)!r}: {what}")
    return bags, skipped


@dataclass
class AnalyzedBag:
    """One bag's run and statistics."""

    path: Path
    run: RecordedRun
    metrics: Metrics
    timing: dict[str, float] | None
    diverged: str = ""
    """Why the run counts as diverged (:meth:`DivergenceCheck.recorded`), or ``""``: such a run is
    left out of the comparisons and of the comparison figures' scales."""

    @property
    def label(self) -> str:
        d = self.run.description
        name = LAWS[d['controller']].label if d['controller'] in LAWS else d['controller']
        return f"{name} ({self.path.name}){' DIVERGED' if self.diverged else ''}"

    def as_dict(self) -> dict[str, Any]:
        out = self.metrics.as_dict()
        out["bag"] = str(self.path)
        out["run"] = self.run.description
        out["complete"] = self.run.complete
        out["missing_steps"] = self.run.missing
        out["diverged"] = self.diverged
        if self.timing is not None:
            out["controller_timing"] = self.timing
        return out


def controller_timing(path: Path, period: float) -> dict[str, float] | None:
    """Jitter and missed deadlines of a real-time run (``/pdsmc/controller_timing``)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    rows = []
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic == "/pdsmc/controller_timing"]
        for conn, _, raw in reader.messages(connections=conns):
            msg: Any = reader.deserialize(raw, conn.msgtype)
            rows.append(msg.data)  # one or more 5-value rows
    data = np.concatenate(rows).reshape(-1, 5) if rows else np.empty((0, 5))
    if len(data) < 3:
        return None
    periods = data[1:, 1]
    jitter = np.abs(periods - period)
    return {
        "ticks": int(len(data)),
        "period_mean_s": float(periods.mean()),
        "jitter_p50_s": float(np.percentile(jitter, 50)),
        "jitter_p99_s": float(np.percentile(jitter, 99)),
        "jitter_max_s": float(jitter.max()),
        "missed_deadlines": int(data[-1, 4]) if data.shape[1] > 4 else 0,
        "missed_pct": float(100.0 * (data[-1, 4] if data.shape[1] > 4 else 0) / len(data)),
    }


def analyze_bag(path: str | Path) -> AnalyzedBag:
    path = Path(path)
    run = read_run(path)
    if not np.any(~np.isnan(run.q[:, 0])):
        raise BagError(f"bag {str(path)!r} holds no joint states")
    try:
        metrics = run_metrics(run)
    except InvalidInputError:
        d = run.description
        recorded = ", ".join(f"{topic} {count}" for topic, count in run.counts.items())
        raise BagError(
            f"bag {str(path)!r} ({d['robot']}/{d['contour']}/{d['controller']} run"
            f"{', truncated' if run.truncated else ''}) holds no control step with its state, reference "
            f"and torque: nothing to analyse (recorded: {recorded})"
        ) from None
    timing = None
    if run.description.get("mode") == "realtime":
        timing = controller_timing(path, 1.0 / run.spec.rate)
    robot = run.spec.robot_model()
    n = robot.n
    applied = run.tau[:-1, :n]  # the last step's command closes the run; it is not applied
    limit = robot.effort_limits if run.spec.enforce_limits else np.full(n, np.inf)
    with np.errstate(invalid="ignore"):
        saturated = (np.abs(applied) >= limit).sum(axis=0)
    metrics = dataclasses.replace(metrics, saturated_periods=[int(c) for c in saturated])
    diverged = DivergenceCheck.for_robot(robot).recorded(run.q[:, :n], run.qd[:, :n], run.tau[:, :n],
                                                         robot.effort_limits, run.spec.rate)
    return AnalyzedBag(path, run, metrics, timing, diverged)


def comparison_table(bags: Sequence[AnalyzedBag]) -> str:
    """Thesis-style table of the bags' statistics, plus relative improvements."""
    lines = []
    header = f"{'statistic':26s}" + "".join(f"{b.label:>24s}" for b in bags)
    lines.append(header)
    lines.append("-" * len(header))
    n = len(bags[0].metrics.axial_mean)

    def row(name: str, values: list[float], fmt: str = "{:.4e}") -> None:
        lines.append(f"{name:26s}" + "".join(f"{fmt.format(v):>24s}" for v in values))

    for i in range(n):
        row(
            f"axis {i + 1} mean (rad)",
            [b.metrics.axial_mean[i] if i < len(b.metrics.axial_mean) else float("nan") for b in bags],
        )
        row(
            f"axis {i + 1} S.D. (rad)",
            [b.metrics.axial_sd[i] if i < len(b.metrics.axial_sd) else float("nan") for b in bags],
        )
    for key in ("x", "y", "total"):
        row(f"task {key} mean (m)", [b.metrics.task_mean[key] for b in bags])
        row(f"task {key} S.D. (m)", [b.metrics.task_sd[key] for b in bags])
    row("contour mean (m)", [b.metrics.contour_mean for b in bags])
    row("contour S.D. (m)", [b.metrics.contour_sd for b in bags])
    row("% within bound", [b.metrics.contour_within_pct for b in bags], "{:.2f} %")
    for i in range(n):
        row(
            f"max |tau_{i + 1}| (N m)",
            [b.metrics.max_torque[i] if i < len(b.metrics.max_torque) else float("nan") for b in bags],
            "{:.4g}",
        )
    for i in range(n):
        row(f"saturated periods {i + 1}",
            [b.metrics.saturated_periods[i] if i < len(b.metrics.saturated_periods) else float("nan")
             for b in bags], "{:.0f}")
    for key, name, fmt in SCORE_ROWS:  # scores beside the errors (docs/SCORES.md), of the same samples
        for i in range(n):
            row(f"{name} {i + 1}", [_score(b.metrics, key, i) for b in bags], fmt)
        row(f"{name} run", [b.metrics.run_scores.get(key, float("nan")) for b in bags], fmt)
    for b in bags:
        if b.diverged:
            lines.append(f"{b.label}: {b.diverged}; left out of the comparisons")
    for b in bags:
        if b.timing:
            t = b.timing
            lines.append(
                f"{b.label}: real time, period {1e6 * t['period_mean_s']:.0f} us, jitter p99 "
                f"{1e6 * t['jitter_p99_s']:.0f} us, missed deadlines {t['missed_deadlines']} "
                f"({t['missed_pct']:.2f} %)"
            )
    lines.extend(loop_report_lines(bags))  # real time: each loop node's overrun statistics
    lines.extend(improvements(bags))
    return "\n".join(lines)


SCORE_ROWS = (("error_rms", "RMS error (rad)", "{:.4e}"), ("error_itae", "ITAE (rad s^2)", "{:.4e}"),
              ("torque_tv_rate", "torque TV/s (N m/s)", "{:.4g}"), ("torque_hf_share",
                                                                      f"power > {DEFAULT_CUTOFF_HZ:g} Hz", "{:.4f}"),
              ("control_energy", "energy (N^2 m^2 s)", "{:.4g}"), ("torque_rate_peak", "peak dtau/dt (N m/s)",
                                                                     "{:.4g}"))
"""The comparison table's score rows: key, label, format (a bag's scores use the default cutoff)."""


def _score(metrics: Metrics, key: str, joint: int) -> float:
    values = getattr(metrics, key)
    return float(values[joint]) if joint < len(values) else float("nan")


def improvements(bags: Sequence[AnalyzedBag]) -> list[str]:
    """Sentences like the thesis's: "PD-SMC: 16.8 % smaller mean contour error than PD" (diverged
    runs compared with none)."""
    out = []
    for a in bags:
        for b in bags:
            if a is b or a.diverged or b.diverged:
                continue
            ma, mb = a.metrics.contour_mean, b.metrics.contour_mean
            if ma < mb:
                out.append(f"{a.label}: {100 * (mb - ma) / mb:.1f} % smaller mean contour error than {b.label}")
    return out


def write_outputs(bags: Sequence[AnalyzedBag], out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    json_path = out / "analysis.json"
    json_path.write_text(json.dumps([b.as_dict() for b in bags], indent=1), encoding="utf-8")
    csv_path = out / "analysis.csv"
    with csv_path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["bag", "robot", "contour", "controller", "scenario", "statistic", "value"])
        for b in bags:
            d = b.run.description
            for key, value in b.metrics.as_dict().items():
                values = value.items() if isinstance(value, dict) else (
                    [(f"{i + 1}", v) for i, v in enumerate(value)] if isinstance(value, list) else [("", value)]
                )
                for sub, v in values:
                    name = f"{key}.{sub}" if sub else key
                    writer.writerow(
                        [str(b.path), d["robot"], d["contour"], d["controller"], d["scenario"], name, repr(v)]
                    )
    return [json_path, csv_path]


# --------------------------------------------------------------------------- #
# A graph the recorder did not start: a real arm's run, analysed per goal
# --------------------------------------------------------------------------- #
@dataclass
class AnalyzedGraphBag:
    """A graph recording's run (:mod:`pdsmc_ros.bag.graph`) and its goals' figures."""

    path: Path
    run: GraphRun
    arm: str  # where the limits came from
    rate: float  # the joint states' rate, Hz
    late_periods: int
    goals: list[GoalFigures]
    diverged: str = ""
    loop_statistics: dict[str, dict[str, float]] = dataclasses.field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {"bag": str(self.path), "kind": "graph", "arm": self.arm, "joints": self.run.names,
                "joint_states": {"topic": self.run.state_topic, "count": len(self.run.t), "rate_hz": self.rate,
                                 "late_periods": self.late_periods},
                "counts": self.run.counts, "diverged": self.diverged, "loop_statistics": self.loop_statistics,
                "goals": [g.as_dict() for g in self.goals]}


def _arm(run: GraphRun, robot: str | None) -> tuple[Any, str]:
    """The arm whose limits apply: ``robot`` if given, else the bag's ``/robot_description``; (None, why) if neither."""
    from ..robots.catalog import ROBOT_DESCRIPTION, register_description, resolve_robot
    from ..robots.registry import make_robot

    if robot is not None:
        try:
            return make_robot(resolve_robot(robot)), f"{robot} (--robot)"
        except ConfigError as exc:
            raise InvalidInputError(f"--robot: {exc}") from None
    if run.urdf is None:
        return None, "unknown: the bag holds no /robot_description (give --robot)"
    try:
        register_description(run.urdf)
        return make_robot(ROBOT_DESCRIPTION), "the bag's /robot_description"
    except (ConfigError, InvalidInputError) as exc:
        return None, f"unknown: the bag's /robot_description cannot be read ({exc})"


def _in_order(run: GraphRun, names: Sequence[str]) -> GraphRun:
    """``run`` with its joint columns in the order of ``names`` (BagError if the states lack one)."""
    missing = [name for name in names if name not in run.names]
    if missing:
        raise BagError(f"bag {str(run.path)!r}: the arm's joints {missing} are not in {run.state_topic} "
                       f"(it has {run.names})")
    index = [run.names.index(name) for name in names]

    def pick(values: np.ndarray) -> np.ndarray:
        return values[:, index]

    reference = dataclasses.replace(run.reference, q=pick(run.reference.q), qd=pick(run.reference.qd))
    goals = [dataclasses.replace(g, desired=None if g.desired is None else dataclasses.replace(
        g.desired, q=pick(g.desired.q), qd=pick(g.desired.qd))) for g in run.goals]
    return dataclasses.replace(run, names=list(names), q=pick(run.q), qd=pick(run.qd), effort=pick(run.effort),
                               reference=reference, goals=goals)


def analyze_graph_bag(path: str | Path, *, robot: str | None = None,
                      settle_band: float = DEFAULT_SETTLE_BAND) -> AnalyzedGraphBag:
    """Per-goal figures of a graph recording (a real arm's run, or the MuJoCo stand-in's).

    Raises
    ------
    BagError
        If the bag cannot be read, holds no joint states or lacks the arm's joints.
    InvalidInputError
        If ``robot`` names no arm or ``settle_band`` is not positive.
    """
    from ..bag.loop_statistics import bag_loop_statistics

    path = Path(path)
    run = read_graph_run(path)
    arm, source = _arm(run, robot)
    if arm is not None:
        run = _in_order(run, arm.joint_names)
    n = len(run.names)
    try:
        period = nominal_period(run.t)
    except InvalidInputError as exc:
        raise BagError(f"bag {str(path)!r}: {exc}") from None
    velocity = arm.velocity_limits if arm is not None else np.full(n, np.inf)
    effort = arm.effort_limits if arm is not None else np.full(n, np.inf)
    goals = run_goal_figures(run, velocity_limits=velocity, effort_limits=effort, settle_band=settle_band)
    diverged = ""
    if arm is not None:
        diverged = DivergenceCheck.for_robot(arm).recorded(run.q, run.qd, run.effort, effort, 1.0 / period)
    return AnalyzedGraphBag(path, run, source, 1.0 / period, late_periods(run.t, period), goals, diverged,
                            bag_loop_statistics(path))


def _fmt(value: float | None, fmt: str) -> str:
    return "-" if value is None or (isinstance(value, float) and np.isnan(value)) else fmt.format(value)


def goal_table(bag: AnalyzedGraphBag) -> str:
    """One column per goal: its result, errors, settling, velocities, torques, scores and periods."""
    run, goals = bag.run, bag.goals
    lines = [(f"{bag.path}: a recorded graph, {len(run.t)} joint states on {run.state_topic} at {bag.rate:.1f} Hz "
              f"({bag.late_periods} late periods), {len(goals)} goal{'s' if len(goals) != 1 else ''}; limits of "
              f"{bag.arm}")]
    if not goals:
        lines.append("no action goal recorded (none was sent, or the action's status was not: recorder actions:=[...])")
        return "\n".join(lines)
    width = max(26, *(len(g.result) + len(g.status) + 5 for g in goals))
    header = f"{'statistic':30s}" + "".join(f"{g.label:>{width}s}" for g in goals)
    lines += [header, "-" * len(header)]

    def row(name: str, values: Sequence[str]) -> None:
        lines.append(f"{name:30s}" + "".join(f"{v:>{width}s}" for v in values))

    row("result", [f"{g.status} ({g.result})" for g in goals])
    row("start (s)", [_fmt(g.start, "{:.3f}") for g in goals])
    row("duration (s)", [_fmt(None if g.end is None else g.end - g.start, "{:.3f}") for g in goals])
    row("goal trajectory", [g.trajectory for g in goals])
    row("desired state from", [g.reference.split(" (")[0] + (" (sparse)" if "too sparse" in g.reference else "")
                               for g in goals])
    for i in range(len(run.names)):
        row(f"axis {i + 1} mean |e| (rad)", [_fmt(g.metrics.axial_mean[i] if g.metrics else None, "{:.4e}")
                                           for g in goals])
        row(f"axis {i + 1} S.D. (rad)", [_fmt(g.metrics.axial_sd[i] if g.metrics else None, "{:.4e}") for g in goals])
        row(f"axis {i + 1} max |e| (rad)", [_fmt(g.error_max[i], "{:.4e}") for g in goals])
    row("desired motion ends (s)", [_fmt(g.reference_end, "{:.3f}") for g in goals])
    row("settle time (s)", [_fmt(g.settle_time, "{:.3f}") if g.settle_time is not None else "not settled"
                            for g in goals])
    for i in range(len(run.names)):
        row(f"max |qd_{i + 1}| (rad/s)", [f"{g.velocity_max[i]:.4g} ({100 * g.velocity_share[i]:.0f} %)"
                                          if np.isfinite(g.velocity_share[i]) else _fmt(g.velocity_max[i], "{:.4g}")
                                          for g in goals])
    for i in range(len(run.names)):
        row(f"max |tau_{i + 1}| (N m)", [_fmt(g.metrics.max_torque[i] if g.metrics else None, "{:.4g}")
                                         for g in goals])
    for i in range(len(run.names)):
        row(f"saturated periods {i + 1}", [_fmt(g.metrics.saturated_periods[i] if g.metrics else None, "{:.0f}")
                                           for g in goals])
    for key, name, fmt in SCORE_ROWS:
        for i in range(len(run.names)):
            row(f"{name} {i + 1}", [_fmt(_score(g.metrics, key, i) if g.metrics else None, fmt) for g in goals])
        row(f"{name} run", [_fmt(g.metrics.run_scores.get(key) if g.metrics else None, fmt) for g in goals])
    row("late periods", [str(g.late_periods) for g in goals])
    lines.append(f"joints: {', '.join(f'{i + 1} {name}' for i, name in enumerate(run.names))}; velocities in % "
                 "of the limit; settle time from the end of the desired motion")
    for g in goals:
        if g.error_string:
            lines.append(f"{g.label}: {g.error_string}")
        if "too sparse" in g.reference:
            lines.append(f"{g.label}: desired state from {g.reference}")
    if bag.diverged:
        lines.append(f"{bag.path}: the run {bag.diverged}")
    lines += format_loop_statistics(str(bag.path), bag.loop_statistics)
    return "\n".join(lines)


def write_graph_outputs(bags: Sequence[AnalyzedGraphBag], out: Path) -> list[Path]:
    """``goals.json`` (every figure) and ``goals.csv`` (bag, goal, statistic, value) in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    json_path = out / "goals.json"
    json_path.write_text(json.dumps([b.as_dict() for b in bags], indent=1), encoding="utf-8")
    csv_path = out / "goals.csv"
    with csv_path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["bag", "goal", "status", "result", "statistic", "value"])
        for b in bags:
            for g in b.goals:
                flat = {k: v for k, v in g.as_dict().items() if k != "metrics"}
                if g.metrics is not None:
                    flat.update(g.metrics.as_dict())
                for key, value in flat.items():
                    values = value.items() if isinstance(value, dict) else (
                        [(f"{i + 1}", v) for i, v in enumerate(value)] if isinstance(value, list) else [("", value)])
                    for sub, v in values:
                        writer.writerow([str(b.path), g.index, g.status, g.result, f"{key}.{sub}" if sub else key,
                                         repr(v)])
    return [json_path, csv_path]
