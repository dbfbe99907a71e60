"""MuJoCo, an independent engine given only the arms' descriptions, against our models (issue 25).

MuJoCo reads each arm's URDF with its own parser (masses, centres, inertia tensors, axes,
damping); only the motor inertia (``armature``) and gravity are set beside it. Its mass
matrix and bias forces must equal ours at random states, and a short closed-loop run in it
must equal the same run in our plant.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.robots.catalog import resolve_robot
from pdsmc_ros.robots.registry import make_robot, unregister_robot

mujoco = pytest.importorskip("mujoco")

from pdsmc_ros.mujoco_driver.driver import MujocoDriver, default_positions, initial_passive  # noqa: E402
from pdsmc_ros.sim import mujoco_model as mm  # noqa: E402
from pdsmc_ros.sim.plant import PlantStepper  # noqa: E402

TIGHT = 1e-10  # relative to the largest entry: both sides are exact rigid-body algorithms


def random_states(n: int, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(-np.pi, np.pi, (count, n)), rng.uniform(-3.0, 3.0, (count, n))


@pytest.mark.parametrize("robot", ["serial_3r", "ur5", "panda"])
def test_mass_matrix_and_bias_equal_ours(robot: str) -> None:
    resolve_robot(robot)
    arm = mm.build_model(robot)
    ours = make_robot(robot)
    data = arm.data()
    qs, qds = random_states(arm.n, 20, seed=len(robot))
    for q, qd in zip(qs, qds, strict=True):
        mm.set_state(arm, data, q, qd)
        m_mujoco = mm.mass_matrix(arm, data)
        m_ours = ours.mass_matrix(q)
        assert np.max(np.abs(m_mujoco - m_ours)) <= TIGHT * np.max(np.abs(m_ours)), (q, m_mujoco, m_ours)
        # C(q, qd) qd + G(q) + B qd: our inverse dynamics at zero acceleration
        bias_ours = ours.inverse_dynamics(q, qd, np.zeros(arm.n))
        bias_mujoco = mm.bias_forces(arm, data)
        assert np.max(np.abs(bias_mujoco - bias_ours)) <= TIGHT * np.max(np.abs(bias_ours)), (q, qd)


def test_the_serial_arms_motor_terms_are_in_mujocos_model() -> None:
    """The thesis's J and B reach MuJoCo as armature and joint damping (not through our matrices)."""
    arm = mm.build_model("serial_3r")
    np.testing.assert_array_equal(arm.model.dof_armature, [0.05, 0.05, 0.05])
    np.testing.assert_array_equal(arm.model.dof_damping, [0.07, 0.07, 0.07])
    np.testing.assert_array_equal(arm.model.opt.gravity, [0.0, 0.0, -9.81])
    assert arm.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4


def test_a_urdf_arm_of_the_users_with_armature(tmp_path: Path) -> None:
    """An arm the project's config does not know: two links, damping in the URDF, armature in the
    YAML beside it, gravity partly along the first joint's axis."""
    link = ('<link name="{name}"><inertial><origin xyz="0.2 0.01 0" rpy="0.1 0.2 0.3"/><mass value="{m}"/>'
            '<inertia ixx="0.02" ixy="0.001" ixz="0" iyy="0.03" iyz="0.002" izz="0.04"/></inertial></link>')
    joint = ('<joint name="{name}" type="revolute"><parent link="{p}"/><child link="{c}"/>'
             '<origin xyz="{x} 0 0.1" rpy="0 0.3 0"/><axis xyz="{axis}"/>'
             '<limit lower="-3" upper="3" effort="{e}" velocity="3"/><dynamics damping="{b}"/></joint>')
    urdf = ('<robot name="two"><link name="base"/>'
            + joint.format(name="a", p="base", c="l1", x=0.0, axis="0 0.6 0.8", e=40, b=0.2)
            + link.format(name="l1", m=2.0)
            + joint.format(name="b", p="l1", c="l2", x=0.4, axis="0 1 0", e=6, b=0.05)
            + link.format(name="l2", m=1.0) + "</robot>")
    path = tmp_path / "two.urdf"
    path.write_text(urdf)
    (tmp_path / "two.yaml").write_text("armature: [0.3, 0.1]\n")
    name = resolve_robot(str(path))
    try:
        arm = mm.build_model(name)
        ours = make_robot(name)
        np.testing.assert_array_equal(arm.effort_limits, [40.0, 6.0])
        data = arm.data()
        for q, qd in zip(*random_states(2, 10, seed=3), strict=True):
            mm.set_state(arm, data, q, qd)
            np.testing.assert_allclose(mm.mass_matrix(arm, data), ours.mass_matrix(q), rtol=0, atol=1e-12)
            np.testing.assert_allclose(mm.bias_forces(arm, data), ours.inverse_dynamics(q, qd, [0.0, 0.0]),
                                       rtol=0, atol=1e-11)
    finally:
        unregister_robot(name)


def test_five_bar_closed_by_a_connect_constraint() -> None:
    """The five-bar's open tree plus MuJoCo's (soft) loop closure against our reduced model: the
    actuated joints' accelerations at closed states agree to a few parts per million of what the
    closure changes."""
    arm = mm.build_model("parallel_5r")
    ours = make_robot("parallel_5r")
    data = arm.data()
    q0 = default_positions("parallel_5r")
    rng = np.random.default_rng(5)
    for _ in range(10):
        q = q0 + rng.uniform(-0.1, 0.1, 2)
        qd, tau = rng.uniform(-1.0, 1.0, 2), rng.uniform(-1.0, 1.0, 2)
        passive, passive_rates = ours.passive_joints(q, qd)
        data.qpos[arm.qpos] = np.concatenate([q, passive])
        data.qvel[arm.dof] = np.concatenate([qd, passive_rates])
        data.ctrl[:] = tau
        mujoco.mj_forward(arm.model, data)
        expected = ours.forward_dynamics(q, qd, tau)
        # the soft constraint leaves a fixed small share of its own correction undone (about 5e-6
        # here: its impedance is MuJoCo's largest, 0.9999, its time constant two steps)
        correction = np.max(np.abs(data.qacc_smooth - data.qacc))
        assert correction > 1.0  # the closure does act
        assert np.max(np.abs(data.qacc[arm.dof[:2]] - expected)) <= 1e-5 * correction


@pytest.mark.parametrize("robot", ["serial_3r", "parallel_5r", "ur5"])
def test_a_pd_run_in_mujoco_equals_our_plant(robot: str) -> None:
    """0.5 s of a PD loop at 1 kHz (torque held over each period) in the driver and in our plant."""
    resolve_robot(robot)
    arm = mm.build_model(robot, timestep=1e-3)
    q0 = default_positions(robot)
    driver = MujocoDriver(arm, q0, passive0=initial_passive(robot, q0))
    plant = PlantStepper(make_robot(robot), 1e-3, q0, np.zeros(arm.n))
    target, kp, kd = q0 + 0.2, 100.0, 10.0
    for k in range(500):
        q, qd, _ = driver.state()
        assert driver.command(kp * (target - q[:arm.n]) - kd * qd[:arm.n], k * 1e-3) is None
        driver.advance((k + 1) * 1e-3)
        plant.step(kp * (target - plant.q) - kd * plant.qd)
    q, qd, _ = driver.state()
    assert np.max(np.abs(plant.q - q0)) > 0.15  # it moved
    tolerance = 1e-12 if robot != "parallel_5r" else 1e-8  # the five-bar's closure is a soft constraint
    np.testing.assert_allclose(q[:arm.n], plant.q, rtol=0, atol=tolerance)
    np.testing.assert_allclose(qd[:arm.n], plant.qd, rtol=0, atol=100 * tolerance)


def test_bad_descriptions_are_one_line() -> None:
    with pytest.raises(InvalidInputError, match="unknown robot 'no_such_arm'; allowed: serial_3r"):
        mm.build_model("no_such_arm")
    with pytest.raises(InvalidInputError, match="timestep"):
        mm.build_model("serial_3r", timestep=0.0)
    with pytest.raises(InvalidInputError, match="integrator"):
        mm.build_model("serial_3r", integrator="leapfrog")
    urdf = mm.description("serial_3r")[0]
    with pytest.raises(InvalidInputError, match="no joint 'finger'"):
        mm.mujoco_urdf(urdf, locked_joints=("finger",))
