"""The new-arm path as typed (issue 37, item 6): one robot whatever the spelling of its URDF's
path, and a joint the plant cannot integrate named with its fix."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from pdsmc_ros.cli import main as pdsmc
from pdsmc_ros.control.registry import Gains
from pdsmc_ros.control.stability import RK4_REAL_LIMIT, plant_step
from pdsmc_ros.errors import ConfigError
from pdsmc_ros.experiments.tuning import tune
from pdsmc_ros.parameters.params_file import write_params_file
from pdsmc_ros.robots import make_robot
from pdsmc_ros.robots.catalog import example_robot_data_dir, resolve_robot
from pdsmc_ros.robots.options import robot_key
from pdsmc_ros.runs.builder import make_run

GAINS = {"kp": [400.0, 400.0, 200.0, 20.0], "kd": [20.0, 20.0, 10.0, 1.0]}


def write_arm(directory: Path, *, name: str = "myarm", wrist_damping: float = 0.1,
              armature: list[float] | None = None) -> Path:
    """A yaw joint and three pitch joints in a vertical plane; ``wrist_damping`` on the last one."""
    def link(link_name: str, mass: float, com: str, inertia: float) -> str:
        return (f'  <link name="{link_name}"><inertial><origin xyz="{com}" rpy="0 0 0"/><mass value="{mass}"/>'
                f'<inertia ixx="{inertia}" ixy="0" ixz="0" iyy="{inertia}" iyz="0" izz="{inertia}"/>'
                '</inertial></link>\n')

    def joint(joint_name: str, parent: str, child: str, xyz: str, axis: str, damping: float = 0.1) -> str:
        return (f'  <joint name="{joint_name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
                f'<origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>'
                '<limit lower="-3.0" upper="3.0" effort="100" velocity="3.0"/>'
                f'<dynamics damping="{damping}" friction="0"/></joint>\n')

    urdf = (f'<?xml version="1.0"?>\n<robot name="{name}">\n  <link name="base_link"/>\n'
            + joint("yaw", "base_link", "l1", "0 0 0", "0 0 1") + link("l1", 3.0, "0 0 0.15", 0.02)
            + joint("shoulder", "l1", "l2", "0 0 0.3", "0 -1 0") + link("l2", 2.0, "0.2 0 0", 0.03)
            + joint("elbow", "l2", "l3", "0.4 0 0", "0 -1 0") + link("l3", 1.5, "0.175 0 0", 0.015)
            + joint("wrist", "l3", "l4", "0.35 0 0", "0 -1 0", wrist_damping) + link("l4", 0.5, "0.05 0 0", 0.001)
            + '  <joint name="tool_joint" type="fixed"><parent link="l4"/><child link="tool0"/>'
            '<origin xyz="0.1 0 0" rpy="0 0 0"/></joint>\n  <link name="tool0"/>\n</robot>\n')
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.urdf"
    path.write_text(urdf)
    options = {"armature": armature or [0.05, 0.05, 0.02, 0.01], "ee_frame": "tool0", "home": [0.0, 0.6, -1.2, 0.4],
               "contour_size": 0.1, "control_rate": 1000.0, "sample_rate": 500.0, "contour_bound": 1.0e-3}
    (directory / f"{name}.yaml").write_text(yaml.safe_dump(options))
    return path


@pytest.fixture
def home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A home directory and a working directory: ``tmp_path/home/work``."""
    directory = tmp_path / "home"
    (directory / "work").mkdir(parents=True)
    monkeypatch.setenv("HOME", str(directory))
    monkeypatch.chdir(directory / "work")
    return directory


def spellings(path: Path, home: Path) -> list[str]:
    """The path relative to the working directory, with ``./``, absolute, from ``~``, through ``..``."""
    relative = os.path.relpath(path, Path.cwd())
    return [relative, f"./{relative}", str(path), "~/" + str(path.relative_to(home)),
            str(path.parent / ".." / path.parent.name / path.name)]


def test_every_spelling_of_a_urdf_path_is_one_robot(home: Path) -> None:
    path = write_arm(home / "work" / "arms")
    link = home / "link.urdf"  # a symbolic link is followed
    link.symlink_to(path)
    shutil.copy(path.with_suffix(".yaml"), home / "link.yaml")
    names = [*spellings(path, home), str(link)]
    keys = {robot_key(name) for name in names}
    assert keys == {str(path.resolve())}
    assert {resolve_robot(name) for name in names} == keys
    for name in names:  # every spelling builds the arm, the one asked by included
        assert make_robot(name).n == 4 and make_robot(name).joint_names == ("yaw", "shoulder", "elbow", "wrist")
    assert robot_key("ur5") == "ur5" and robot_key("serial_3r") == "serial_3r"


def test_a_missing_file_is_named_as_given_and_as_found(home: Path) -> None:
    with pytest.raises(ConfigError, match=r"robot '~/nowhere.urdf': no such URDF file \(" + str(home)):
        resolve_robot("~/nowhere.urdf")


def test_params_file_of_one_spelling_serves_every_other(home: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_arm(home / "work" / "arms")
    relative = os.path.relpath(path, Path.cwd())
    params = home / "work" / "p.yaml"
    gains = Gains.from_mapping(GAINS, 4, "pd")
    write_params_file(params, gains, controller="pd", robot=relative, contour="circle", rate=1000.0)
    written = yaml.safe_load(params.read_text())["/**"]["ros__parameters"]["robot"]
    assert written == str(path.resolve())  # absolute: the file serves from any directory
    for name in spellings(path, home):
        code = pdsmc(["check-gains", "--robot", name, "--contour", "circle", "--controller", "pd",
                      "--params-file", str(params)])
        out = capsys.readouterr()
        assert "give the same" not in out.err and "pdsmc check-gains: error" not in out.err, (name, out.err)
        assert code in (0, 1) and "gains kp=[400.0, 400.0, 200.0, 20.0]" in out.out, (name, out)
    other = write_arm(home / "work" / "other", name="other")  # another arm is still refused
    assert pdsmc(["check-gains", "--robot", str(other), "--contour", "circle", "--controller", "pd",
                  "--params-file", str(params)]) != 0
    assert "give the same, or leave one out" in capsys.readouterr().err


def test_tune_names_the_joint_that_needs_armature_or_a_faster_loop(home: Path) -> None:
    path = write_arm(home / "work" / "arms", wrist_damping=6.0, armature=[0.05, 0.05, 0.02, 0.0])
    with pytest.raises(ConfigError) as info:
        tune(str(path), "circle", "pd", rounds=1)
    message = str(info.value)
    assert "joint 'wrist': damping/inertia x period = " in message and "> 1.39" in message
    assert "armature >= " in message and " kg m^2 for 'wrist'" in message and "--rate " in message
    figure = float(message.split("x period = ")[1].split()[0])
    armature = float(message.split("armature >= ")[1].split()[0])
    rate = float(message.split("--rate ")[1].split()[0])
    robot = make_robot(str(path))
    reference = make_run(str(path), "circle", "pd", gains=Gains.from_mapping(GAINS, 4, "pd")).reference()
    q = reference.sample(np.linspace(0.0, reference.duration, 13)).q
    assert figure == pytest.approx(plant_step(robot, q, 1000.0).figure, rel=1e-2) and figure > RK4_REAL_LIMIT / 2
    assert plant_step(robot, q, rate).holds and not plant_step(robot, q, 0.9 * rate).holds
    fixed = write_arm(home / "work" / "fixed", wrist_damping=6.0, armature=[0.05, 0.05, 0.02, armature])
    assert plant_step(make_robot(resolve_robot(str(fixed))), q, 1000.0).holds


def test_check_gains_names_that_joint_too(home: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_arm(home / "work" / "arms", wrist_damping=6.0, armature=[0.05, 0.05, 0.02, 0.0])
    code = pdsmc(["check-gains", "--robot", str(path), "--contour", "circle", "--controller", "pd",
                  *(f"--gain={k}={','.join(map(str, v))}" for k, v in GAINS.items())])
    out = capsys.readouterr().out
    assert code == 1 and "plant step at 1000 Hz FAILS: joint 'wrist': damping/inertia x period" in out


def test_the_xarm7_of_example_robot_data_names_its_last_joint() -> None:
    try:
        urdf = example_robot_data_dir() / "xarm_description" / "urdf" / "xarm7.urdf"
    except ConfigError:
        pytest.skip("example-robot-data is not installed")
    robot = make_robot(resolve_robot(str(urdf)))
    q = np.zeros((1, robot.n))
    step = plant_step(robot, q, 1000.0)
    assert step.joint == "joint7" and 13.0 < step.figure < 16.0 and not step.holds  # the 14
    assert "joint7" in dict(step.armature)  # and joint1 (damping 10), at this configuration
    with_armature = robot.J.copy()
    for name, value in step.armature:  # the fix it names
        with_armature[robot.joint_names.index(name)] = value
    robot.J = with_armature
    assert plant_step(robot, q, 1000.0).holds
    assert plant_step(make_robot(resolve_robot(str(urdf))), q, step.rate).holds  # or the rate it names
