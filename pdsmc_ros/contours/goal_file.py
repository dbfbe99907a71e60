"""FollowJointTrajectory goal files: the goal as YAML in the message's own layout.

What ``ros2 action send_goal <action> control_msgs/action/FollowJointTrajectory "$(cat goal.yaml)"``
takes on a full ROS 2 install, and what ``pdsmc send-goal goal.yaml`` sends here::

    trajectory:
      header: {stamp: {sec: 0, nanosec: 0}, frame_id: ''}
      joint_names: [joint_a, joint_b]
      points:
      - positions: [0.0, 0.0]
        velocities: [0.0, 0.0]
        accelerations: [0.0, 0.0]
        effort: []
        time_from_start: {sec: 0, nanosec: 0}
      - ...
    path_tolerance: []        # control_msgs/JointTolerance: {name, position, velocity, acceleration}
    goal_tolerance: []
    goal_time_tolerance: {sec: 0, nanosec: 0}

A stamp of zero means "start now" (joint_trajectory_controller's rule). :func:`read_goal` checks
the shape and the types of every field it knows, in one line naming the file and the field;
the joint-trajectory controller itself decides whether the goal is valid for the arm (its joints,
its times, its tolerances), as it does for any client.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike

from ..checks import are_real, is_real, is_whole
from ..errors import ConfigError
from ..robots.base import FloatArray

__all__ = ["GOAL_KEYS", "duration", "goal_data", "read_goal", "seconds", "write_goal"]

GOAL_KEYS = ("trajectory", "multi_dof_trajectory", "path_tolerance", "component_path_tolerance", "goal_tolerance",
             "component_goal_tolerance", "goal_time_tolerance")
"""The fields of ``control_msgs/action/FollowJointTrajectory``'s goal (Jazzy)."""
POINT_KEYS = ("positions", "velocities", "accelerations", "effort", "time_from_start")
TOLERANCE_KEYS = ("name", "position", "velocity", "acceleration")


def duration(t: float) -> dict[str, int]:
    """``builtin_interfaces/Duration`` of ``t`` seconds (``nanosec`` in [0, 1e9))."""
    whole = math.floor(t)
    nanosec = int(round((t - whole) * 1e9))
    if nanosec >= 1_000_000_000:
        whole, nanosec = whole + 1, nanosec - 1_000_000_000
    return {"sec": int(whole), "nanosec": nanosec}


def seconds(value: Mapping[str, Any]) -> float:
    return float(value["sec"]) + 1e-9 * float(value["nanosec"])


def goal_data(joint_names: Sequence[str], times: ArrayLike, positions: ArrayLike, velocities: ArrayLike | None = None,
              accelerations: ArrayLike | None = None, *, goal_time_tolerance: float = 0.0) -> dict[str, Any]:
    """A goal's plain data: one point per time (``positions`` etc. ``(k, n)``), stamp zero, no tolerances
    (the controller's own)."""
    t = np.asarray(times, dtype=float)
    q = np.asarray(positions, dtype=float)
    qd = None if velocities is None else np.asarray(velocities, dtype=float)
    qdd = None if accelerations is None else np.asarray(accelerations, dtype=float)
    points = []
    for k in range(len(t)):
        points.append({
            "positions": _digits(q[k]),
            "velocities": [] if qd is None else _digits(qd[k]),
            "accelerations": [] if qdd is None else _digits(qdd[k]),
            "effort": [],
            "time_from_start": duration(float(t[k])),
        })
    return {
        "trajectory": {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
                       "joint_names": list(joint_names), "points": points},
        "path_tolerance": [],
        "goal_tolerance": [],
        "goal_time_tolerance": duration(goal_time_tolerance),
    }


def _digits(values: FloatArray) -> list[float]:
    """Ten significant digits: below a nanoradian on any joint angle, half the file of full ``repr``."""
    return [float(f"{v:.10g}") for v in values]


def write_goal(path: str | Path, goal: Mapping[str, Any], comment: str = "") -> None:
    """``goal`` as YAML (lists inline: one line per point), after a comment."""
    header = "".join(f"# {line}\n" for line in comment.splitlines())
    Path(path).write_text(header + yaml.dump(dict(goal), Dumper=_dumper(), sort_keys=False, default_flow_style=None,
                                             width=1 << 16))


def _dumper() -> type:
    return getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def _loader() -> type:
    return getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def read_goal(path: str | Path) -> dict[str, Any]:
    """A goal file's plain data, its shape checked.

    Raises
    ------
    ConfigError
        One line naming the file and the field: no such file, not YAML, an unknown key, a field
        of the wrong type, a point whose fields are not numbers, a duration that is not
        ``{sec, nanosec}``, a trajectory without joints or points.
    """
    label = f"goal file {str(path)!r}"
    try:
        text = Path(path).read_text()
    except FileNotFoundError:
        raise ConfigError(f"{label}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{label}: cannot read it ({exc})") from None
    try:
        data = yaml.load(text, Loader=_loader())  # noqa: S506 - a safe loader (C or Python)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{label} is not YAML: {str(exc).splitlines()[0]}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{label}: expected a FollowJointTrajectory goal (a mapping with trajectory: ...), got "
                          f"{type(data).__name__}")
    unknown = sorted(set(data) - set(GOAL_KEYS))
    if unknown:
        raise ConfigError(f"{label}: unknown key(s) {unknown}; a FollowJointTrajectory goal has {', '.join(GOAL_KEYS)}")
    trajectory = data.get("trajectory")
    if not isinstance(trajectory, dict):
        raise ConfigError(f"{label}: trajectory must be a mapping (header, joint_names, points)")
    bad = sorted(set(trajectory) - {"header", "joint_names", "points"})
    if bad:
        raise ConfigError(f"{label}: trajectory has unknown key(s) {bad}; allowed: header, joint_names, points")
    header = trajectory.get("header", {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""})
    if not isinstance(header, dict) or set(header) - {"stamp", "frame_id"}:
        raise ConfigError(f"{label}: trajectory.header must be {{stamp: {{sec, nanosec}}, frame_id}}")
    _check_duration(header.get("stamp", {"sec": 0, "nanosec": 0}), f"{label}: trajectory.header.stamp")
    names = trajectory.get("joint_names")
    if not isinstance(names, list) or not names or not all(isinstance(j, str) for j in names):
        raise ConfigError(f"{label}: trajectory.joint_names must be a non-empty list of joint names")
    points = trajectory.get("points")
    if not isinstance(points, list) or not points:
        raise ConfigError(f"{label}: trajectory.points must be a non-empty list of points")
    for i, point in enumerate(points):
        where = f"{label}: trajectory.points[{i}]"
        if not isinstance(point, dict):
            raise ConfigError(f"{where} must be a mapping ({', '.join(POINT_KEYS)})")
        extra = sorted(set(point) - set(POINT_KEYS))
        if extra:
            raise ConfigError(f"{where} has unknown key(s) {extra}; allowed: {', '.join(POINT_KEYS)}")
        for key in POINT_KEYS[:4]:
            values = point.get(key, [])
            if not isinstance(values, list) or not are_real(values):
                raise ConfigError(f"{where}.{key} must be a list of numbers, got {values!r}")
        _check_duration(point.get("time_from_start"), f"{where}.time_from_start")
    for key in ("path_tolerance", "goal_tolerance"):
        tolerances = data.get(key, [])
        if not isinstance(tolerances, list):
            raise ConfigError(f"{label}: {key} must be a list of {{name, position, velocity, acceleration}}")
        for i, tol in enumerate(tolerances):
            if not isinstance(tol, dict) or set(tol) - set(TOLERANCE_KEYS) or not isinstance(tol.get("name"), str) \
                    or not all(is_real(tol.get(k, 0.0)) for k in TOLERANCE_KEYS[1:]):
                raise ConfigError(f"{label}: {key}[{i}] must be {{name: joint, position, velocity, acceleration}} "
                                  f"(numbers), got {tol!r}")
    for key in ("multi_dof_trajectory", "component_path_tolerance", "component_goal_tolerance"):
        value = data.get(key)
        if value not in (None, [], {}) and not (key == "multi_dof_trajectory" and isinstance(value, dict)
                                                and not value.get("points") and not value.get("joint_names")):
            raise ConfigError(f"{label}: {key} is not supported by pdsmc send-goal (leave it empty)")
    _check_duration(data.get("goal_time_tolerance", {"sec": 0, "nanosec": 0}), f"{label}: goal_time_tolerance")
    return data


def _check_duration(value: Any, where: str) -> None:
    if not (isinstance(value, dict) and set(value) == {"sec", "nanosec"} and is_whole(value["sec"])
            and is_whole(value["nanosec"]) and 0 <= value["nanosec"] < 1_000_000_000):
        raise ConfigError(f"{where} must be {{sec: N, nanosec: N}} (whole numbers, nanosec below 1e9), got {value!r}")
