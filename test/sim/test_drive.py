"""Each nuisance of the MuJoCo stand-in against an expectation computed here, not by the drive:
Coulomb friction that holds a joint and reads back from our own dynamics, the encoder's grid, the
command delay counted in ticks, the torque's lag and torque-speed line from their formulas, the
differenced and filtered velocity by scipy's filter, the noise's spread and seed, and the payload's
gravity torque from Pinocchio and by hand (ROS-free; the driver as the node runs it, on a clock of
our own)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco")

from pdsmc_ros.mujoco_driver import driver as md  # noqa: E402
from pdsmc_ros.robots.catalog import resolve_robot  # noqa: E402
from pdsmc_ros.robots.registry import make_robot  # noqa: E402
from pdsmc_ros.sim.drive import lowpass_gain  # noqa: E402
from pdsmc_ros.sim.mujoco_model import bias_forces, build_stand_in  # noqa: E402

RATE = 1000.0
T = 1.0 / RATE


def stand_in(robot: str, *, gravity: bool = True, preset: str = "ideal", seed: int = 0, **given: object
             ) -> md.MujocoDriver:
    """A driver of ``robot`` at 1 kHz with these nuisances (gravity off: none acts on the joints)."""
    arm, realism, _ = build_stand_in(robot, rate=RATE, preset=preset, given=given, seed=seed)
    if not gravity:
        arm.model.opt.gravity[:] = 0.0
    return md.MujocoDriver(arm, md.default_positions(robot), command_timeout=0.0, realism=realism,
                           effort_limits=make_robot(resolve_robot(robot)).effort_limits)


def ticks(driver: md.MujocoDriver, start: float, count: int) -> float:
    """``count`` ticks of the driver from wall time ``start`` (one each call); the time reached."""
    for k in range(1, count + 1):
        driver.advance(start + k * T)
    return start + count * T


# --------------------------------------------------------------------------- #
# friction
# --------------------------------------------------------------------------- #
@pytest.mark.parametrize("share", [0.5, 0.9, 0.99])
def test_a_torque_below_the_coulomb_friction_does_not_move_a_joint_without_gravity(share: float) -> None:
    fc = np.array([3.0, 3.0, 3.0, 0.8, 0.8, 0.8])
    d = stand_in("ur5", gravity=False, friction_coulomb=fc.tolist())
    q0 = d.true_state()[0][:6].copy()
    d.command((share * fc).tolist(), 0.0)
    ticks(d, 0.0, 1000)
    q, qd, _ = d.true_state()
    assert np.max(np.abs(q[:6] - q0)) < 1e-4  # sticks (MuJoCo's soft constraint creeps by 1e-5 in 1 s)
    assert np.max(np.abs(qd[:6])) < 1e-4
    for j in range(6):  # well above it, a joint alone slides
        beyond = stand_in("ur5", gravity=False, friction_coulomb=fc.tolist())
        push = np.zeros(6)
        push[j] = 1.5 * fc[j]
        beyond.command(push.tolist(), 0.0)
        ticks(beyond, 0.0, 1000)
        assert abs(beyond.true_state()[0][j] - q0[j]) > 0.05, f"joint {j + 1} did not slide"


def test_the_friction_reads_back_from_our_own_model_of_the_arm() -> None:
    """The serial 3R's torque minus our model's ``Mbar qdd + C qd + G + B qd`` on MuJoCo's motion is
    the stand-in's friction: ``fc sign(qd) + fv qd`` within a few per cent (the stiff solref_friction)."""
    fc, fv = np.array([4.0, 2.0, 1.0]), np.array([0.5, 0.3, 0.2])
    d = stand_in("serial_3r", friction_coulomb=fc.tolist(), friction_viscous=fv.tolist())
    model = make_robot("serial_3r")
    rows = []
    t = 0.0
    for k in range(2000):
        q, qd, _ = d.true_state()
        tau = model.inverse_dynamics(q, qd, np.zeros(3)) + 2.5 * fc * np.sin(2 * np.pi * np.array([1.0, 1.3, 1.7])
                                                                              * k * T)
        d.command(tau.tolist(), t)
        t = ticks(d, t, 1)
        q1, qd1, _ = d.true_state()
        a = (qd1 - qd) / T
        mid_q, mid_qd = 0.5 * (q + q1), 0.5 * (qd + qd1)
        friction = tau - model.inverse_dynamics(mid_q, mid_qd, a)
        rows.append((mid_qd, friction))
    qd = np.array([r[0] for r in rows])
    f = np.array([r[1] for r in rows])
    for j in range(3):
        moving = np.abs(qd[:, j]) > 0.05
        assert moving.sum() > 200
        design = np.column_stack([np.sign(qd[moving, j]), qd[moving, j]])
        (fc_fit, fv_fit), *_ = np.linalg.lstsq(design, f[moving, j], rcond=None)
        assert fc_fit == pytest.approx(fc[j], rel=0.05)
        assert fv_fit == pytest.approx(fv[j], rel=0.15, abs=0.05)


# --------------------------------------------------------------------------- #
# what the drive publishes
# --------------------------------------------------------------------------- #
def test_positions_are_on_the_encoders_grid() -> None:
    counts = np.array([4096, 1000, 2**18])
    d = stand_in("serial_3r", encoder_counts=counts.tolist())
    d.command([0.0, 0.0, 0.0], 0.0)  # the arm falls: positions sweep many counts
    seen = []
    t = 0.0
    for _ in range(300):
        t = ticks(d, t, 1)
        seen.append(d.state()[0][:3])
    positions = np.array(seen)
    grid = 2 * np.pi / counts
    np.testing.assert_allclose(positions / grid, np.round(positions / grid), atol=1e-6)
    true = d.true_state()[0][:3]
    assert np.all(np.abs(positions[-1] - true) <= grid / 2 + 1e-12)  # the nearest count
    assert len(np.unique(positions[:, 0])) > 10


def test_the_differenced_velocity_is_scipys_filter_of_the_positions_differences() -> None:
    from scipy.signal import lfilter

    cutoff = np.array([100.0, 30.0, 0.0])
    d = stand_in("serial_3r", velocity_source="difference", velocity_filter_hz=cutoff.tolist(),
                 encoder_counts=[2**14] * 3)
    d.command([0.0, 0.0, 0.0], 0.0)
    published = []
    t = 0.0
    for _ in range(400):
        t = ticks(d, t, 1)
        published.append(d.state()[:2])
    q = np.array([p[0][:3] for p in published])
    v = np.array([p[1][:3] for p in published])
    raw = np.diff(q, axis=0) / T
    for j in range(3):
        a = float(lowpass_gain(T, cutoff[j]))
        if cutoff[j] > 0:
            assert a == pytest.approx(T / (T + 1 / (2 * np.pi * cutoff[j])))  # libfranka's gain
        # y[k] = a x[k] + (1 - a) y[k-1], from the state the filter had before the first of ``raw``
        expected = lfilter([a], [1.0, -(1.0 - a)], raw[:, j], zi=[(1.0 - a) * v[0, j]])[0]
        np.testing.assert_allclose(v[1:, j], expected, rtol=1e-9, atol=1e-9)
    exact = stand_in("serial_3r")
    exact.command([0.0, 0.0, 0.0], 0.0)
    ticks(exact, 0.0, 50)
    np.testing.assert_array_equal(exact.state()[1], exact.true_state()[1])  # exact: MuJoCo's own


def test_position_noise_has_its_spread_and_repeats_with_its_seed() -> None:
    sd = np.array([1e-3, 2e-3, 0.0])

    def readings(seed: int) -> tuple[np.ndarray, np.ndarray]:
        d = stand_in("serial_3r", position_noise=sd.tolist(), seed=seed)
        out, true = [], []
        t = 0.0
        for _ in range(4000):  # braked: the arm at rest, the noise alone
            t = ticks(d, t, 1)
            out.append(d.state()[0][:3])
            true.append(d.true_state()[0][:3])
        return np.array(out), np.array(true)

    a, true = readings(7)
    error = a - true
    np.testing.assert_allclose(error.std(axis=0)[:2], sd[:2], rtol=0.05)
    assert np.all(np.abs(error.mean(axis=0)[:2]) < 4 * sd[:2] / np.sqrt(len(error)))
    np.testing.assert_array_equal(error[:, 2], 0.0)
    np.testing.assert_array_equal(readings(7)[0], a)  # the same seed: the same run
    assert not np.array_equal(readings(8)[0], a)


# --------------------------------------------------------------------------- #
# what a command does
# --------------------------------------------------------------------------- #
@pytest.mark.parametrize("delay", [0, 1, 3, 7])
def test_a_commands_effect_comes_command_delay_ticks_later(delay: int) -> None:
    d = stand_in("ur5", gravity=False, command_delay=delay)
    q0 = d.true_state()[0].copy()
    d.command([1.0] * 6, 0.0)  # the first command: the motors get it ``delay`` ticks later
    t = 0.0
    for k in range(1, delay + 1):
        t = ticks(d, t, 1)
        np.testing.assert_array_equal(d.true_state()[0], q0, err_msg=f"moved at tick {k} of {delay}")
    t = ticks(d, t, 1)
    assert np.all(d.true_state()[0][:6] != q0[:6])
    t = ticks(d, t, 5)
    d.command([-2.0] * 6, t)  # a later command, arriving between two ticks
    applied = []
    for _ in range(delay + 2):
        t = ticks(d, t, 1)
        applied.append(d.true_state()[2][:6].copy())  # the motors' torque over the tick just run
    for k, torque in enumerate(applied, start=1):
        expected = -2.0 if k > delay else 1.0
        np.testing.assert_array_equal(torque, expected, err_msg=f"tick {k} after the command, delay {delay}")


def test_the_torque_lags_its_command_as_a_first_order_filter() -> None:
    bandwidth = 50.0
    d = stand_in("ur5", gravity=False, torque_bandwidth_hz=bandwidth)
    d.command([2.0] * 6, 0.0)
    a = T / (T + 1 / (2 * np.pi * bandwidth))
    t = 0.0
    for k in range(1, 30):
        t = ticks(d, t, 1)
        np.testing.assert_allclose(d.true_state()[2][:6], 2.0 * (1 - (1 - a) ** k), rtol=1e-12)


def test_the_torque_falls_with_speed_along_the_motors_line() -> None:
    d = stand_in("ur5", gravity=False, torque_speed=True, no_load_speed=2.0)
    effort = make_robot(resolve_robot("ur5")).effort_limits
    d.command(effort.tolist(), 0.0)  # the full torque: the line bounds it as the joints speed up
    t = 0.0
    checked = 0
    for _ in range(400):
        v = d.true_state()[1][:6].copy()
        t = ticks(d, t, 1)
        expected = np.minimum(effort * (1.0 - np.clip(v, -4.0, 4.0) / 2.0), effort)
        np.testing.assert_allclose(d.true_state()[2][:6], expected, rtol=1e-12, atol=1e-12)
        checked += int(np.any(v > 0.5))
    assert checked > 50  # the joints did reach speeds where the line bites
    # held about the no-load speed (the joints' coupling pushes some a little beyond: the line brakes them)
    assert np.all(np.abs(d.true_state()[1][:6] - 2.0) < 0.2)


# --------------------------------------------------------------------------- #
# the payload
# --------------------------------------------------------------------------- #
def test_the_payloads_gravity_torque_is_pinocchios_on_the_ur5() -> None:
    pin = pytest.importorskip("pinocchio")
    mass, com = 1.3, np.array([0.02, -0.03, 0.08])
    loaded, _, _ = build_stand_in("ur5", rate=RATE, given={"payload_mass": mass, "payload_com": com.tolist()})
    bare, _, _ = build_stand_in("ur5", rate=RATE)
    robot = make_robot(resolve_robot("ur5"))
    model = pin.buildModelFromXML(robot.model_source()[0])
    data = model.createData()
    frame = model.getFrameId("tool0")
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-np.pi, np.pi, 6)
        g = []
        for arm in (loaded, bare):
            d = arm.data()
            d.qpos[arm.qpos[:6]] = q
            g.append(bias_forces(arm, d))
        pin.framesForwardKinematics(model, data, q)
        placement = data.oMf[frame]
        point = placement.act(com)
        jacobian = pin.computeFrameJacobian(model, data, q, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        r = point - placement.translation
        skew = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
        j_point = jacobian[:3] - skew @ jacobian[3:]
        expected = j_point.T @ (mass * np.array([0.0, 0.0, 9.81]))  # G = -J^T m g, g along -z
        np.testing.assert_allclose(g[0] - g[1], expected, rtol=1e-9, atol=1e-9)


def test_the_payloads_gravity_torque_on_the_serial_arm_by_hand() -> None:
    """The thesis serial 3R in the URDF's x-z plane (joints about -y, gravity -z): a point mass ``m`` at
    ``(c_x, c_z)`` in the tool frame (the tip of link 3, its axes) pulls each joint by ``m g`` times
    the horizontal distance from the joint to the mass."""
    mass, cx, cz = 0.4, 0.05, 0.03
    loaded, _, _ = build_stand_in("serial_3r", rate=RATE, given={"payload_mass": mass,
                                                                 "payload_com": [cx, 0.0, cz]})
    bare, _, _ = build_stand_in("serial_3r", rate=RATE)
    lengths = [link.length for link in make_robot("serial_3r").params.links]
    q = np.array([0.4, -0.9, 1.2])
    angles = np.cumsum(q)
    joints_x = np.concatenate([[0.0], np.cumsum([lengths[i] * math.cos(angles[i]) for i in range(3)])])
    tip_angle = angles[2]
    # the tool frame's x along link 3, its z the link's normal in the plane (x rotated by +90 degrees)
    mass_x = joints_x[3] + cx * math.cos(tip_angle) - cz * math.sin(tip_angle)
    expected = [mass * 9.81 * (mass_x - joints_x[i]) for i in range(3)]
    g = []
    for arm in (loaded, bare):
        d = arm.data()
        d.qpos[arm.qpos[:3]] = q
        g.append(bias_forces(arm, d))
    np.testing.assert_allclose(g[0] - g[1], expected, rtol=1e-9)
