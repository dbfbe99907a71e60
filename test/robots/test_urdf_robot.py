"""URDF arms through Pinocchio (issue 16): the thesis's serial arm from its URDF reproduces the
built-in runs; real arms follow the thesis's contours in a plane; bad input is one line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from pdsmc_ros.contours import JointReference  # noqa: E402
from pdsmc_ros.errors import ConfigError, InvalidInputError, UnreachableError  # noqa: E402
from pdsmc_ros.resources import config_dir  # noqa: E402
from pdsmc_ros.robots import Serial3R, make_robot, robot_params  # noqa: E402
from pdsmc_ros.robots.catalog import resolve_robot  # noqa: E402
from pdsmc_ros.robots.task import TaskPlane, rotation_log  # noqa: E402
from pdsmc_ros.robots.urdf import robot_urdf  # noqa: E402
from pdsmc_ros.robots.urdf_robot import from_urdf  # noqa: E402
from pdsmc_ros.runs.builder import build_contour, make_run  # noqa: E402
from pdsmc_ros.sim import simulate  # noqa: E402

PARAMS = robot_params("serial_3r")
THESIS_PLANE = TaskPlane(origin=np.zeros(3), u=np.array([1.0, 0.0, 0.0]), v=np.array([0.0, 0.0, 1.0]))
SERIAL_URDF = str(config_dir() / "urdf" / "serial_3r.urdf")


def serial_from_urdf(tmp_path: Path):  # noqa: ANN201
    path = tmp_path / "serial_3r.urdf"
    path.write_text(robot_urdf("serial_3r", PARAMS))
    return from_urdf(path, armature=PARAMS.motor_inertia, ee_frame="tool0", plane=THESIS_PLANE)


def wrapped(angle: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * angle))


def test_the_serial_arm_from_its_urdf_has_the_built_in_dynamics(tmp_path: Path) -> None:
    urdf, built_in = serial_from_urdf(tmp_path), Serial3R()
    assert urdf.joint_names == ("joint1", "joint2", "joint3") and urdf.n == 3
    assert urdf.orientation == "contour" and urdf.rows.tolist() == [0, 1, 5]  # planar: x, z, pose
    np.testing.assert_array_equal(urdf.B, built_in.B)  # <dynamics damping> is the motor damping
    rng = np.random.default_rng(16)
    for _ in range(20):
        q, qd, tau = rng.uniform(-3, 3, 3), rng.uniform(-2, 2, 3), rng.uniform(-20, 20, 3)
        np.testing.assert_allclose(urdf.mass_matrix(q), built_in.mass_matrix(q), rtol=0, atol=1e-9)
        # the Christoffel C itself, not only C qd
        np.testing.assert_allclose(urdf.coriolis_matrix(q, qd), built_in.coriolis_matrix(q, qd), rtol=0, atol=1e-9)
        np.testing.assert_allclose(urdf.gravity(q), built_in.gravity(q), rtol=0, atol=1e-9)
        np.testing.assert_allclose(urdf.forward_dynamics(q, qd, tau), built_in.forward_dynamics(q, qd, tau),
                                   rtol=0, atol=1e-9)
        # the thesis plane (x, y) is the URDF's (x, z); the pose is the sum of the angles
        u, v, pose = urdf.forward_kinematics(q)
        x, y, built_pose = built_in.forward_kinematics(q)
        np.testing.assert_allclose([u, v], [x, y], rtol=0, atol=1e-12)
        assert abs(wrapped(pose - built_pose)) < 1e-12
        np.testing.assert_allclose(urdf.jacobian(q), built_in.jacobian(q), rtol=0, atol=1e-12)
    q = rng.uniform(-3, 3, (4, 3))  # a batch, as the built-in robots take
    np.testing.assert_allclose(urdf.mass_matrix(q), built_in.mass_matrix(q), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(urdf.torque_limit, [1e6] * 3)


@pytest.mark.parametrize("contour", ["zigzag", "diamond", "circle", "ellipse"])
def test_the_serial_urdf_reproduces_the_built_in_runs(contour: str) -> None:
    """config/urdf/serial_3r.urdf through the generic path (Pinocchio model, compiled serial chain,
    numerical inverse kinematics) against the hand-derived arm, three laws on each contour."""
    assert resolve_robot(SERIAL_URDF) == SERIAL_URDF
    for controller in ("pd", "smc", "pdsmc"):
        built_in = simulate(make_run("serial_3r", contour, controller))
        urdf = simulate(make_run(SERIAL_URDF, contour, controller))
        a, b = built_in.samples, urdf.samples
        assert a.q.shape == b.q.shape
        # joint angles agree up to whole turns (the inverse kinematics start from another seed)
        assert np.max(np.abs(wrapped(a.q - b.q))) <= 1e-9, controller
        assert np.max(np.abs(a.xy - b.xy)) <= 1e-9, controller
        # references 1e-14 rad apart (the IK tolerance) are torques ~1e-10 N m apart at Kp ~ 1e4
        assert np.max(np.abs(a.tau - b.tau)) <= 1e-9 * np.max(np.abs(a.tau)), controller
        assert abs(built_in.metrics.contour_mean - urdf.metrics.contour_mean) <= 1e-9
        np.testing.assert_allclose(urdf.metrics.axial_mean, built_in.metrics.axial_mean, rtol=0, atol=1e-9)


def test_a_ur5_follows_the_circle_in_its_plane_with_the_tool_held() -> None:
    robot, contour = make_robot(resolve_robot("ur5")), build_contour("ur5", "circle")
    assert robot.orientation == "held" and robot.rows.tolist() == [0, 1, 2, 3, 4, 5]
    low, high = contour.extent()
    assert np.isclose(np.max(high - low), robot.settings["contour_size"])  # fitted to the arm
    reference = JointReference(robot, contour)
    t = np.linspace(0.0, contour.duration, 401)
    sample = reference.sample(t)
    np.testing.assert_allclose(robot.position(sample.q), contour.task(t).p[:, :2], rtol=0, atol=1e-10)
    for q in sample.q[::40]:
        x, r = robot.ee_pose(q)
        assert abs(robot.plane.normal @ (x - robot.plane.origin)) < 1e-10  # in the plane
        assert np.linalg.norm(rotation_log(r @ robot.reference_rotation.T)) < 1e-10  # tool held
    # rates are the derivatives of the angles (finite differences on a fine grid)
    fine = np.linspace(1.0, 1.01, 101)
    dense = reference.sample(fine)
    np.testing.assert_allclose(np.gradient(dense.q, fine, axis=0)[2:-2], dense.qd[2:-2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.gradient(dense.qd, fine, axis=0)[2:-2], dense.qdd[2:-2], rtol=0, atol=1e-5)


def test_a_contour_out_of_reach_is_refused_naming_its_point_and_time(tmp_path: Path) -> None:
    path = tmp_path / "arm.urdf"
    path.write_text(robot_urdf("serial_3r", PARAMS))
    (tmp_path / "arm.yaml").write_text(
        "armature: 0.05\nee_frame: tool0\nhome: [0.3, 1.2, -0.5]\n"
        "plane: {origin: [0, 0, 0], u: [1, 0, 0], v: [0, 0, 1]}\ncontour_size: 3.0\ngains: serial_3r\n")
    with pytest.raises(UnreachableError, match=r"contour 'circle' leaves the .*arm.urdf workspace at t = [0-9.]+ s"):
        make_run(str(path), "circle", "pd").reference()


def test_robots_by_name_and_by_path_and_bad_ones(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"unknown robot 'ur55'; allowed: serial_3r, parallel_5r, .*ur5.*"
                                          r"or a path to a \.urdf file"):
        resolve_robot("ur55")
    with pytest.raises(ConfigError, match="no such URDF file"):
        resolve_robot(str(tmp_path / "missing.urdf"))
    path = tmp_path / "typo.urdf"
    path.write_text(robot_urdf("serial_3r", PARAMS))
    (tmp_path / "typo.yaml").write_text("armatur: 0.05\n")
    with pytest.raises(ConfigError, match=r"typo.yaml: unknown key\(s\) \['armatur'\]"):
        resolve_robot(str(path))


def test_bad_urdfs_are_one_line_naming_the_problem(tmp_path: Path) -> None:
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'></robot>")
    with pytest.raises(InvalidInputError, match="does not parse") as info:
        from_urdf(broken)
    assert "\n" not in str(info.value) and "broken.urdf" in str(info.value)
    with pytest.raises(InvalidInputError, match="no such file"):
        from_urdf(tmp_path / "missing.urdf")
    fixed_only = ("<robot name='f'><link name='a'/><link name='b'/><joint name='j' type='fixed'>"
                  "<parent link='a'/><child link='b'/></joint></robot>")
    with pytest.raises(InvalidInputError, match="no movable joint"):
        from_urdf(fixed_only)
    with pytest.raises(InvalidInputError, match="no frame 'hand'"):
        from_urdf(robot_urdf("serial_3r", PARAMS), ee_frame="hand")
    massless = robot_urdf("serial_3r", PARAMS).replace('<mass value="0.5"/>', '<mass value="0.0"/>')
    with pytest.raises(InvalidInputError, match=r"no mass"):
        from_urdf(massless)
    with pytest.raises(InvalidInputError, match="armature of joint 'joint1' must be finite >= 0, got -1.0"):
        from_urdf(robot_urdf("serial_3r", PARAMS), armature=[-1.0, 0.0, 0.0])
    tree = robot_urdf("parallel_5r", robot_params("parallel_5r"))  # the five-bar's open tree
    with pytest.raises(InvalidInputError, match="not a serial chain: joint 'joint2' branches off"):
        from_urdf(tree)


def test_the_cli_takes_a_urdf_file_and_refuses_a_broken_one_in_one_line(tmp_path: Path) -> None:
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'></robot>")
    proc = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "simulate", "--robot", str(broken), "--contour",
                           "circle", "--controller", "pd"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "does not parse" in proc.stderr and "Traceback" not in proc.stderr


def test_cached_kernels_built_from_other_sources_are_dropped(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """numba checks a cached kernel against its own file only: after a change to another kernel
    module (the robot dispatch, say) the package's cache must not survive."""
    from pdsmc_ros.kernels import cache as kernel_cache

    sources = kernel_cache.kernel_sources()
    assert {p.name for p in sources} >= {"compiled.py", "loop.py", "spatial_layout.py", "spatial_kernels.py",
                                         "spatial_dynamics.py", "ik_kernels.py", "kernel_math.py",
                                         "options.py"}
    cache = tmp_path / "cache"
    cache.mkdir()
    stale = cache / "loop._closed_loop_compiled-22.py311.nbi"
    stale.write_text("x")
    other = cache / "someone_elses.f-1.py311.nbi"
    other.write_text("x")
    monkeypatch.setattr(kernel_cache, "cache_dirs", lambda _sources: {cache})
    monkeypatch.setattr(kernel_cache, "_done", False)
    kernel_cache.refresh()
    assert not stale.exists() and other.exists()
    marker = cache / (kernel_cache.MARKER_PREFIX + kernel_cache.digest(sources))
    assert marker.exists()
    stale.write_text("x")  # written by this version: kept
    monkeypatch.setattr(kernel_cache, "_done", False)
    kernel_cache.refresh()
    assert stale.exists()


def test_the_published_description_rebuilds_the_same_arm() -> None:
    """A pdsmc_ros plant's /robot_description carries the arm's task options (<pdsmc_ros>), so a
    node given robot:=/robot_description follows the same references as one given robot:=ur5."""
    from pdsmc_ros.robots.catalog import ROBOT_DESCRIPTION, register_description

    ur5 = make_robot(resolve_robot("ur5"))
    xml = ur5.description()
    assert "<pdsmc_ros>" in xml and xml.rstrip().endswith("</robot>")
    assert register_description(xml) == ROBOT_DESCRIPTION
    again = make_robot(ROBOT_DESCRIPTION)
    assert again.joint_names == ur5.joint_names and again.orientation == ur5.orientation
    np.testing.assert_array_equal(again.home, ur5.home)
    np.testing.assert_array_equal(again.plane.origin, ur5.plane.origin)
    assert again.settings == {**ur5.settings, "gains": "ur5"}  # its presets by name
    a = make_run("ur5", "circle", "pdsmc").reference().sample(np.linspace(0, 5, 11))
    b = make_run(ROBOT_DESCRIPTION, "circle", "pdsmc").reference().sample(np.linspace(0, 5, 11))
    np.testing.assert_array_equal(a.q, b.q)
    # an arm's URDF from another publisher (no <pdsmc_ros>): the defaults
    plain = register_description(ur5.urdf)
    assert make_robot(plain).orientation == "held" and np.all(make_robot(plain).home == 0.0)
    with pytest.raises(ConfigError, match="does not parse"):
        register_description("<robot")


def test_simulate_a_ur5_prints_the_usual_keys_and_check_gains_runs_for_it() -> None:
    import json

    proc = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "simulate", "--robot", "ur5", "--contour", "circle",
                           "--controller", "pdsmc", "--json"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert {"axial_mean", "axial_sd", "task_mean", "contour_mean", "contour_within_pct", "max_torque"} <= set(result)
    assert len(result["axial_mean"]) == 6 and result["run"]["robot"] == "ur5"
    # the tuned gains track the 0.3 m circle within 2.5 mm (gains that hold with the real-time loop's two
    # periods of delay at margin x2, stability.REALTIME_DELAY_PERIODS: 1.99 mm; those for one period, 0.7 mm)
    assert result["contour_mean"] < 2.5e-3
    check = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "check-gains", "--robot", "ur5", "--contour",
                            "circle", "--controller", "pdsmc"], capture_output=True, text=True, timeout=300)
    assert "discrete-rate condition at 1000 Hz holds" in check.stdout, check.stderr
    assert check.stdout.count("Ks_") == 6  # Eq. 3.19 per joint of the arm


ONE_JOINT_URDF = """<robot name="one">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.25 0 0"/><mass value="1.0"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 -1 0"/>
    <limit effort="20" velocity="5" lower="-3" upper="3"/></joint>
  <link name="tip"/>
  <joint name="tipj" type="fixed"><parent link="l1"/><child link="tip"/><origin xyz="0.5 0 0"/></joint>
</robot>
"""


def test_a_one_joint_arm_is_loaded_and_what_it_cannot_do_is_one_line(tmp_path: Path) -> None:
    """Before: eigenpy's 6 x 1 Jacobian came as a vector and loading the arm was a traceback."""
    (tmp_path / "one.urdf").write_text(ONE_JOINT_URDF)
    (tmp_path / "gains.yaml").write_text("controller:\n  ros__parameters:\n    kp: [100.0]\n    kd: [10.0]\n")
    proc = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "simulate", "--robot", str(tmp_path / "one.urdf"),
                           "--contour", "circle", "--controller", "pd", "--params-file", str(tmp_path / "gains.yaml")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert "one.urdf workspace" in proc.stderr


def test_a_urdf_arm_is_an_instance_of_its_settings_not_a_class_made_at_run_time() -> None:
    """The registry holds the arm (an UrdfArm instance); each robot built from it is a UrdfRobot
    with the arm's settings and its own Pinocchio data; what differs from a thesis arm is a method."""
    from pdsmc_ros.robots import ROBOTS, UrdfArm, UrdfRobot

    name = resolve_robot("ur5")
    assert isinstance(ROBOTS[name], UrdfArm)
    a, b = make_robot(name), make_robot(name)
    assert type(a) is UrdfRobot and type(b) is UrdfRobot and a.arm is b.arm and a.data is not b.data
    assert a.n == 6 and a.joint_names == ROBOTS[name].joint_names
    assert a.contour_set() == "serial_3r" and a.gains_source() == "ur5" and not a.has_link_params
    np.testing.assert_array_equal(a.home_configuration(), a.home)
    with pytest.raises(InvalidInputError, match="a payload on a URDF arm"):
        a.payload_params(1.0)
    serial = make_robot("serial_3r")
    assert serial.contour_set() == "serial_3r" and serial.home_configuration() is None and serial.has_link_params
    assert serial.payload_params(1.5).links[2].mass == robot_params("serial_3r").links[2].mass + 1.5
