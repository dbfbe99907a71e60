"""Contour presets (``config/contours.yaml``) and the contours a run may name (CSV waypoints,
joint via points): which preset set an arm runs, and the contour built from a name."""

from __future__ import annotations

import numpy as np

from ..config import choice, load_config
from ..errors import ConfigError
from ..robots import make_robot
from ..robots.catalog import resolve_robot
from . import (
    Contour,
    EllipseContour,
    JointPath,
    JointPathContour,
    SegmentContour,
    load_joint_waypoints,
    load_waypoints_csv,
)


def contour_names(robot: str) -> tuple[str, ...]:
    """The robot's contour presets (``config/contours.yaml``) and ``csv``."""
    return tuple(load_config("contours").get(contour_set(robot)) or ()) + ("csv", "joints")


def contour_set(robot: str) -> str:
    """Whose contour presets ``robot`` runs: its own, or for a URDF arm the set its settings
    name (the serial arm's by default: the thesis's task-space contours)."""
    return make_robot(resolve_robot(robot)).contour_set()


def contour_preset(
    robot: str,
    name: str,
    *,
    ellipse_error: str,
    waypoints_file: str | None,
    segment_duration: float,
) -> Contour:
    """The named contour preset (or a CSV contour) for ``robot``; the settings' defaults are the run
    table's (:func:`pdsmc_ros.runs.builder.build_contour` applies them).

    A URDF arm runs its contour set's presets fitted to its ``contour_size`` (m, the box's
    longer side, centred on its task plane's origin; none: as they are) and CSV contours as
    given, in its task plane's coordinates.
    """
    model = make_robot(resolve_robot(robot))
    dim = model.task_dim
    if name == "joints":
        if not waypoints_file:
            raise ConfigError("contour 'joints' needs a file of joint via points (--waypoints FILE: CSV "
                              "t, q1..qn or YAML points: [{t, q}])")
        times, points = load_joint_waypoints(waypoints_file, model.n)
        return JointPathContour("joints", model, JointPath(times, points))
    if name == "csv":
        if not waypoints_file:
            raise ConfigError("contour 'csv' needs a waypoints file (--waypoints FILE)")
        pts = load_waypoints_csv(waypoints_file, dim=dim)
        return SegmentContour("csv", pts, segment_duration, metric="nearest")
    preset = _preset_contour(model.contour_set(), name, dim, ellipse_error)
    size = model.contour_size()
    return preset.fitted(size) if size else preset


def _preset_contour(robot: str, name: str, dim: int, ellipse_error: str) -> Contour:
    presets = load_config("contours")[robot]
    spec = presets[choice(name, contour_names(robot), f"contour for {robot}")]
    if spec["type"] == "segments":
        pts = np.asarray(spec["waypoints"], dtype=float)
        if dim == 3:
            pts[:, 2] *= np.pi
        return SegmentContour(name, pts, float(spec["segment_duration"]))
    pose = None
    if dim == 3:
        pose = (float(spec["pose_pi"][0]) * np.pi, float(spec["pose_pi"][1]) * np.pi)
    return EllipseContour(
        name,
        spec["center"],
        float(spec["rx"]),
        float(spec["ry"]),
        float(spec["duration"]),
        pose=pose,
        ellipse_error=ellipse_error,
    )
