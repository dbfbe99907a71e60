"""What the arm is asked to do: task-space contours (Section 4.2), joint-space via points, the
joint references a contour gives through the inverse kinematics, and the polynomial time
scalings they share (the thesis's quintic; joint_trajectory_controller's segments)."""

from .joint_paths import JointPath, JointPathContour, load_joint_waypoints
from .polynomials import quintic, segment
from .reference import JointReference
from .samples import JointSample, TaskSample
from .shapes import Contour, EllipseContour, SegmentContour, ellipse_distance, load_waypoints_csv, polyline_distance

__all__ = [
    "Contour",
    "EllipseContour",
    "JointPath",
    "JointPathContour",
    "JointReference",
    "JointSample",
    "SegmentContour",
    "TaskSample",
    "ellipse_distance",
    "load_joint_waypoints",
    "load_waypoints_csv",
    "polyline_distance",
    "quintic",
    "segment",
]
