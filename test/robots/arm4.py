"""A user's 4-joint arm written by the tests (not taken from the project's config).

Effort limits 40, 40, 20 and 6 N m; the wrist's link is heavy enough (3.5 kg at 0.2 m: 6.9 N m
held level) that its 6 N m cannot hold it level, so a run that asks it to saturates.
"""

from __future__ import annotations

from pathlib import Path

EFFORT = (40.0, 40.0, 20.0, 6.0)
VELOCITY = 2.0
GAINS = {"kp": [400.0, 400.0, 200.0, 100.0], "kd": [40.0, 40.0, 20.0, 10.0]}


def _link(name: str, mass: float, com: float) -> str:
    inertia = max(mass * 0.01, 1e-3)
    return (f'<link name="{name}"><inertial><origin xyz="{com} 0 0"/><mass value="{mass}"/>'
            f'<inertia ixx="{inertia}" ixy="0" ixz="0" iyy="{inertia}" iyz="0" izz="{inertia}"/></inertial></link>')


def _joint(name: str, parent: str, child: str, xyz: str, axis: str, effort: float, kind: str = "revolute") -> str:
    limit = "" if kind == "continuous" else 'lower="-2.5" upper="2.5" '
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}"/><axis xyz="{axis}"/><limit {limit}effort="{effort}" velocity="{VELOCITY}"/>'
            f'<dynamics damping="0.1"/></joint>')


def arm_urdf(*, wrist: str = "revolute") -> str:
    """The arm's URDF; ``wrist="continuous"`` makes its last joint continuous."""
    return "\n".join([
        '<robot name="arm4">', '<link name="base_link"/>',
        _link("link1", 3.0, 0.0), _link("link2", 2.0, 0.15), _link("link3", 1.0, 0.125), _link("link4", 3.5, 0.2),
        '<link name="tool0"/>',
        _joint("base_yaw", "base_link", "link1", "0 0 0.1", "0 0 1", EFFORT[0]),
        _joint("shoulder", "link1", "link2", "0 0 0.1", "0 1 0", EFFORT[1]),
        _joint("elbow", "link2", "link3", "0.3 0 0", "0 1 0", EFFORT[2]),
        _joint("wrist", "link3", "link4", "0.25 0 0", "0 1 0", EFFORT[3], wrist),
        '<joint name="tool" type="fixed"><parent link="link4"/><child link="tool0"/><origin xyz="0.3 0 0"/></joint>',
        "</robot>",
    ])


OPTIONS = f"""\
armature: 0.05
ee_frame: tool0
control_rate: 1000.0
sample_rate: 500.0
contour_bound: 1.0e-3
gains:
  linear:
    pd: {{kp: {GAINS['kp']}, kd: {GAINS['kd']}}}
"""

WAYPOINTS = "0.0, 0.0, 0.0, 0.0, 0.0\n1.0, 0.3, -0.2, 0.2, 0.2\n2.0, 0.0, 0.0, 0.0, 0.0\n"
"""Joint via points (t, q1..q4): the wrist held about level, where it needs more than its 6 N m."""


def write_arm(directory: Path, *, options: str = OPTIONS, wrist: str = "revolute") -> tuple[Path, Path]:
    """``arm4.urdf`` with ``arm4.yaml`` beside it, and the via points; returns (urdf, waypoints)."""
    directory.mkdir(parents=True, exist_ok=True)
    urdf = directory / "arm4.urdf"
    urdf.write_text(arm_urdf(wrist=wrist))
    (directory / "arm4.yaml").write_text(options)
    points = directory / "via.csv"
    points.write_text(WAYPOINTS)
    return urdf, points
