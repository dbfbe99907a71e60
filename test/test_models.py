"""Property and cross-checks of the manipulator models (no ROS needed)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pdsmc_ros.errors import (
    InvalidInputError,
    SingularConfigurationError,
    UnreachableError,
)
from pdsmc_ros.robots import Manipulator, Parallel5R, Serial3R, make_robot, robot_params
from pdsmc_ros.sim import PlantStepper

SERIAL_3R_PARAMS = robot_params("serial_3r")
PARALLEL_5R_PARAMS = robot_params("parallel_5r")
RNG_SEED = 20151


def rk4_step(robot: Manipulator, q: np.ndarray, qd: np.ndarray, tau: np.ndarray,
             h: float) -> tuple[np.ndarray, np.ndarray]:
    """A classical RK4 step of Eq. (4.1) over a batch of states, written here from the numpy model
    (the package's step is compiled, one state at a time: this is its independent reference)."""
    f = robot.forward_dynamics
    a1 = f(q, qd, tau)
    a2 = f(q + 0.5 * h * qd, qd + 0.5 * h * a1, tau)
    a3 = f(q + 0.5 * h * (qd + 0.5 * h * a1), qd + 0.5 * h * a2, tau)
    a4 = f(q + h * (qd + 0.5 * h * a2), qd + h * a3, tau)
    q_next = q + h / 6.0 * (qd + 2.0 * (qd + 0.5 * h * a1) + 2.0 * (qd + 0.5 * h * a2) + qd + h * a3)
    return q_next, qd + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)


def serial_states(rng: np.random.Generator, count: int) -> tuple[np.ndarray, np.ndarray]:
    q = rng.uniform(-np.pi, np.pi, (count, 3))
    qd = rng.uniform(-3.0, 3.0, (count, 3))
    return q, qd


def parallel_states(
    robot: Parallel5R, rng: np.random.Generator, count: int
) -> tuple[np.ndarray, np.ndarray]:
    """Random states over the region every thesis contour of the five-bar visits."""
    radius = 0.065 * np.sqrt(rng.uniform(0.0, 1.0, count))
    angle = rng.uniform(0.0, 2.0 * np.pi, count)
    p = np.stack([0.16 + radius * np.cos(angle), 0.20 + radius * np.sin(angle)], axis=-1)
    q = robot.inverse_kinematics(p)
    qd = rng.uniform(-2.0, 2.0, (count, 2))
    return q, qd


# --------------------------------------------------------------------------- #
# Properties P1, P2 and energy
# --------------------------------------------------------------------------- #
@pytest.mark.parametrize("payload", [0.0, 1.5])
def test_mass_matrix_symmetric_positive_definite(payload: float) -> None:
    rng = np.random.default_rng(RNG_SEED)
    serial = Serial3R(payload)
    q, _ = serial_states(rng, 500)
    m = serial.mass_matrix(q)
    assert np.max(np.abs(m - np.swapaxes(m, -1, -2))) < 1e-14
    assert np.min(np.linalg.eigvalsh(m)) > 0.0

    parallel = Parallel5R(payload)
    q, _ = parallel_states(parallel, rng, 500)
    m = parallel.mass_matrix(q)
    assert np.max(np.abs(m - np.swapaxes(m, -1, -2))) < 1e-14
    assert np.min(np.linalg.eigvalsh(m)) > 0.0


@pytest.mark.parametrize("robot_name", ["serial_3r", "parallel_5r"])
def test_mdot_minus_2c_is_skew_symmetric(robot_name: str) -> None:
    rng = np.random.default_rng(RNG_SEED + 1)
    robot = make_robot(robot_name, payload=0.7)
    if isinstance(robot, Serial3R):
        q, qd = serial_states(rng, 100)
    else:
        q, qd = parallel_states(robot, rng, 100)
    eps = 1e-6
    m_dot = (robot.mass_matrix(q + eps * qd) - robot.mass_matrix(q - eps * qd)) / (2 * eps)
    n = m_dot - 2.0 * robot.coriolis_matrix(q, qd)
    scale = np.max(np.abs(m_dot))
    assert np.max(np.abs(n + np.swapaxes(n, -1, -2))) < 1e-7 * scale
    # and C qd is what forward dynamics uses
    c_vec = np.einsum("...ij,...j->...i", robot.coriolis_matrix(q, qd), qd)
    assert np.allclose(c_vec, robot._coriolis_vector(q, qd), rtol=0, atol=1e-12)


@pytest.mark.parametrize("robot_name", ["serial_3r", "parallel_5r"])
def test_energy_is_conserved_without_torque_and_damping(robot_name: str) -> None:
    rng = np.random.default_rng(RNG_SEED + 2)
    if robot_name == "serial_3r":
        robot = Serial3R(1.5, params=dataclasses.replace(SERIAL_3R_PARAMS, motor_damping=0.0))
        q, qd = serial_states(rng, 6)
    else:
        robot = Parallel5R(params=dataclasses.replace(PARALLEL_5R_PARAMS, motor_damping=0.0))
        q, qd = parallel_states(robot, rng, 6)
        qd = 0.3 * qd  # stay clear of the five-bar's singular configurations
    e0 = robot.total_energy(q, qd)
    # the vectorised reference integrator for 0.05 s, the compiled one for the full 2 s
    qa, qda = q, qd
    for _ in range(500):
        qa, qda = rk4_step(robot, qa, qda, np.zeros_like(q), 1e-4)
    drift = np.abs(robot.total_energy(qa, qda) - e0) / np.abs(e0)
    assert np.max(drift) < 1e-8
    for i in range(len(q)):
        plant = PlantStepper(robot, 1e-4, q[i], qd[i])
        for _ in range(20000):  # 2 s
            plant.step(np.zeros(robot.n))
        drift = abs(robot.total_energy(plant.q, plant.qd) - e0[i]) / abs(e0[i])
        assert drift < 1e-6


def test_damping_dissipates_energy() -> None:
    robot = Serial3R()
    q = np.array([0.3, 0.2, -0.1])
    qd = np.array([1.0, -1.0, 2.0])
    e0 = robot.total_energy(q, qd)
    for _ in range(1000):
        q, qd = rk4_step(robot, q, qd, np.zeros(3), 1e-3)
    assert robot.total_energy(q, qd) < e0


# --------------------------------------------------------------------------- #
# Serial arm against Pinocchio
# --------------------------------------------------------------------------- #
def pinocchio_serial(payload: float):  # noqa: ANN202 - pinocchio types
    pin = pytest.importorskip("pinocchio")
    model = pin.Model()
    parent = 0
    links = SERIAL_3R_PARAMS.links
    for i, link in enumerate(links):
        offset = 0.0 if i == 0 else links[i - 1].length
        placement = pin.SE3(np.eye(3), np.array([offset, 0.0, 0.0]))
        joint = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{i + 1}")
        inertia = pin.Inertia(
            link.mass, np.array([link.com, 0.0, 0.0]), np.diag([0.0, 0.0, link.inertia])
        )
        model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())
        parent = joint
    tip = pin.Inertia(payload, np.array([links[-1].length, 0.0, 0.0]), np.zeros((3, 3)))
    model.appendBodyToJoint(parent, tip, pin.SE3.Identity())
    model.gravity = pin.Motion(np.array([0.0, -9.81, 0.0]), np.zeros(3))
    return pin, model, model.createData()


@pytest.mark.parametrize("payload", [0.0, 1.5])
def test_serial_forward_dynamics_matches_pinocchio(payload: float) -> None:
    pin, model, data = pinocchio_serial(payload)
    robot = Serial3R(payload)
    rng = np.random.default_rng(RNG_SEED + 3)
    q, qd = serial_states(rng, 200)
    tau = rng.uniform(-20.0, 20.0, (200, 3))
    ours = robot.forward_dynamics(q, qd, tau)
    worst = 0.0
    for i in range(200):
        m = pin.crba(model, data, q[i])
        m = np.triu(m) + np.triu(m, 1).T
        nle = pin.nonLinearEffects(model, data, q[i], qd[i])
        ref = np.linalg.solve(m + np.diag(robot.J), tau[i] - nle - robot.B * qd[i])
        worst = max(worst, float(np.max(np.abs(ref - ours[i]))))
        # mass matrix and gravity individually too
        assert np.allclose(m + np.diag(robot.J), robot.mass_matrix(q[i]), rtol=0, atol=1e-12)
        g = pin.computeGeneralizedGravity(model, data, q[i])
        assert np.allclose(g, robot.gravity(q[i]), rtol=0, atol=1e-12)
    assert worst < 1e-9


# --------------------------------------------------------------------------- #
# Parallel arm against a Lagrange-multiplier (KKT) solution of the open tree
# --------------------------------------------------------------------------- #
def appendix_open_tree(qp: np.ndarray, qpd: np.ndarray, payload: float):  # noqa: ANN202
    """M', C', G' of Appendix Eqs. (58)-(69), written out term by term.

    The payload is a point mass at the tip of link 3 (distance L3 from joint 3).
    """
    l1, l2, l3, l4 = (link.mass for link in PARALLEL_5R_PARAMS.links)
    m1, m2, m3, m4 = l1, l2, l3, l4
    links = PARALLEL_5R_PARAMS.links
    L1, L2, L3, L4 = (link.length for link in links)
    r1, r2, r3, r4 = (link.com for link in links)
    i1, i2, i3, i4 = (link.inertia for link in links)
    # fold the payload into link 3 (mass, centre, inertia about the new centre)
    m3p = m3 + payload
    r3p = (m3 * r3 + payload * L3) / m3p
    i3p = i3 + m3 * (r3 - r3p) ** 2 + payload * (L3 - r3p) ** 2
    m3, r3, i3 = m3p, r3p, i3p
    q1, q2, q3, q4 = qp
    g = 9.81
    m = np.zeros((4, 4))
    m[0, 0] = m1 * r1**2 + m3 * (L1**2 + r3**2 + 2 * L1 * r3 * np.cos(q3)) + i1 + i3
    m[0, 2] = m[2, 0] = m3 * (r3**2 + L1 * r3 * np.cos(q3)) + i3
    m[1, 1] = m2 * r2**2 + m4 * (L2**2 + r4**2 + 2 * L2 * r4 * np.cos(q4)) + i2 + i4
    m[1, 3] = m[3, 1] = m4 * (r4**2 + L2 * r4 * np.cos(q4)) + i4
    m[2, 2] = m3 * r3**2 + i3
    m[3, 3] = m4 * r4**2 + i4
    h1 = -m3 * L1 * r3 * np.sin(q3)
    h2 = -m4 * L2 * r4 * np.sin(q4)
    d1, d2, d3, d4 = qpd
    c = np.array(
        [
            [h1 * d3, 0.0, h1 * (d1 + d3), 0.0],
            [0.0, h2 * d4, 0.0, h2 * (d2 + d4)],
            [-h1 * d1, 0.0, 0.0, 0.0],
            [0.0, -h2 * d2, 0.0, 0.0],
        ]
    )
    gv = g * np.array(
        [
            (m1 * r1 + m3 * L1) * np.cos(q1) + m3 * r3 * np.cos(q1 + q3),
            (m2 * r2 + m4 * L2) * np.cos(q2) + m4 * r4 * np.cos(q2 + q4),
            m3 * r3 * np.cos(q1 + q3),
            m4 * r4 * np.cos(q2 + q4),
        ]
    )
    s13, c13 = np.sin(q1 + q3), np.cos(q1 + q3)
    s24, c24 = np.sin(q2 + q4), np.cos(q2 + q4)
    a = np.array(  # Eqs. (48)-(55)
        [
            [-L1 * np.sin(q1) - L3 * s13, L2 * np.sin(q2) + L4 * s24, -L3 * s13, L4 * s24],
            [L1 * np.cos(q1) + L3 * c13, -L2 * np.cos(q2) - L4 * c24, L3 * c13, -L4 * c24],
        ]
    )
    w13, w24 = d1 + d3, d2 + d4
    a_dot = np.array(
        [
            [
                -L1 * np.cos(q1) * d1 - L3 * c13 * w13,
                L2 * np.cos(q2) * d2 + L4 * c24 * w24,
                -L3 * c13 * w13,
                L4 * c24 * w24,
            ],
            [
                -L1 * np.sin(q1) * d1 - L3 * s13 * w13,
                L2 * np.sin(q2) * d2 + L4 * s24 * w24,
                -L3 * s13 * w13,
                L4 * s24 * w24,
            ],
        ]
    )
    return m, c, gv, a, a_dot


@pytest.mark.parametrize("payload", [0.0, 1.5])
def test_parallel_reduced_model_matches_kkt(payload: float) -> None:
    robot = Parallel5R(payload)
    rng = np.random.default_rng(RNG_SEED + 4)
    q, qd = parallel_states(robot, rng, 150)
    tau = rng.uniform(-1.0, 1.0, (150, 2))
    ours = robot.forward_dynamics(q, qd, tau)
    q3q4, q3q4_dot = robot.passive_joints(q, qd)
    worst = 0.0
    for i in range(150):
        qp = np.array([q[i, 0], q[i, 1], q3q4[i, 0], q3q4[i, 1]])
        qpd = np.array([qd[i, 0], qd[i, 1], q3q4_dot[i, 0], q3q4_dot[i, 1]])
        m, c, g, a, a_dot = appendix_open_tree(qp, qpd, payload)
        assert np.allclose(a @ qpd, 0.0, atol=1e-12)  # rates satisfy the loop closure
        m = m.copy()
        m[0, 0] += robot.J[0]
        m[1, 1] += robot.J[1]
        gen_force = np.zeros(4)
        gen_force[:2] = tau[i] - robot.B * qd[i]
        kkt = np.block([[m, a.T], [a, np.zeros((2, 2))]])
        rhs = np.concatenate([gen_force - c @ qpd - g, -a_dot @ qpd])
        sol = np.linalg.solve(kkt, rhs)
        worst = max(worst, float(np.max(np.abs(sol[:2] - ours[i]))))
    assert worst < 1e-8


def test_parallel_loop_closes_and_jacobian_is_consistent() -> None:
    robot = Parallel5R()
    rng = np.random.default_rng(RNG_SEED + 5)
    q, qd = parallel_states(robot, rng, 50)
    left, right = robot.open_tree(q)
    assert np.allclose(robot.left.tip(left), robot.right.tip(right), atol=1e-13)
    eps = 1e-6
    j_fd = (robot.forward_kinematics(q + eps * qd) - robot.forward_kinematics(q - eps * qd)) / (
        2 * eps
    )
    j = np.einsum("...ij,...j->...i", robot.jacobian(q), qd)
    assert np.allclose(j, j_fd, atol=1e-8)


@pytest.mark.parametrize("payload", [0.0, 1.5])
def test_plant_outputs_equal_the_models_kinematics(payload: float) -> None:
    """PlantStepper.outputs (the compiled kernel the plant node publishes from) gives the
    end effector and the five-bar's passive joints of the numpy models."""
    rng = np.random.default_rng(RNG_SEED + 9)
    serial = Serial3R(payload)
    for q, qd in zip(*serial_states(rng, 100)):
        out = PlantStepper(serial, 1e-4, q, qd).outputs()
        assert np.max(np.abs(out[:2] - serial.position(q))) < 1e-14
    parallel = Parallel5R(payload)
    qs, qds = parallel_states(parallel, rng, 100)
    passive_q, passive_qd = parallel.passive_joints(qs, qds)
    for i in range(len(qs)):
        out = PlantStepper(parallel, 1e-4, qs[i], qds[i]).outputs()
        assert np.max(np.abs(out[:2] - parallel.position(qs[i]))) < 1e-13
        assert np.max(np.abs(out[2:4] - passive_q[i])) < 1e-12
        assert np.max(np.abs(out[4:6] - passive_qd[i])) < 1e-10


# --------------------------------------------------------------------------- #
# Inverse kinematics against Tables 4.4 and 4.6
# --------------------------------------------------------------------------- #
SERIAL_TABLE = {
    "zigzag": (
        [(-0.50, 0.0, -0.75), (-0.25, 0.50, -1.0), (0.0, 0.0, -0.5), (0.25, 0.50, 0.0),
         (0.50, 0.0, -0.25)],
        [["7.585", "6.710", "6.588", "6.909", "5.713"],
         ["-3.873", "-4.195", "-3.751", "-4.195", "-3.873"],
         ["-6.069", "-5.657", "-4.408", "-2.715", "-2.626"]],
    ),
    "diamond": (
        [(-0.15, 0.0, 0.0), (0.0, -0.70, -0.5), (0.15, 0.0, -1.0), (0.0, 0.70, -1.5),
         (-0.15, 0.0, -2.0)],
        [["2.038", "3.553", "5.179", "6.695", "8.321"],
         ["2.208", "2.319", "2.208", "2.319", "2.208"],
         ["-4.246", "-7.442", "-10.53", "-13.73", "-16.81"]],
    ),
}

PARALLEL_TABLE = {
    "zigzag": (
        [(0.10, 0.18), (0.13, 0.22), (0.16, 0.18), (0.19, 0.22), (0.22, 0.18)],
        [["3.063", "2.381", "2.366", "1.772", "1.682"],
         ["0.746", "0.706", "0.161", "0.255", "-0.389"],
         ["-2.295", "-1.661", "-1.847", "-1.170", "-1.269"],
         ["1.931", "1.766", "2.265", "1.993", "2.472"]],
    ),
    "diamond": (
        [(0.10, 0.20), (0.16, 0.26), (0.22, 0.20), (0.16, 0.14), (0.10, 0.20)],
        [["2.849", "1.727", "1.562", "2.616", "2.849"],
         ["0.845", "0.768", "-0.142", "-0.269", "0.845"],
         ["-2.063", "-0.918", "-1.062", "-2.205", "-2.063"],
         ["1.772", "1.507", "2.255", "2.681", "1.772"]],
    ),
}


def rounding(text: str) -> float:
    """Half a unit of the last printed digit."""
    decimals = len(text.split(".")[1])
    return 0.5 * 10.0**-decimals + 1e-12


def angle_gap(a: float, b: float) -> float:
    return abs((a - b + np.pi) % (2 * np.pi) - np.pi)


@pytest.mark.parametrize("contour", ["zigzag", "diamond"])
def test_serial_ik_reproduces_table_4_4(contour: str) -> None:
    points, table = SERIAL_TABLE[contour]
    robot = Serial3R()
    for j, (x, y, pose_pi) in enumerate(points):
        q = robot.inverse_kinematics([x, y, pose_pi * np.pi])
        for axis in range(3):
            text = table[axis][j]
            if (contour, j, axis) == ("zigzag", 0, 2):
                continue  # misprint, see test_table_4_4_zigzag_start_q3_is_self_inconsistent
            assert angle_gap(q[axis], float(text)) <= rounding(text), (contour, j, axis, q)
        assert np.allclose(robot.forward_kinematics(q), [x, y, pose_pi * np.pi], atol=1e-12)


def test_table_4_4_zigzag_start_q3_is_self_inconsistent() -> None:
    """Table 4.4 prints q3 = -6.069 at the zigzag start; Eq. (8) of the appendix,
    q3 = q_ee - q1 - q2, applied to the table's own q1 = 7.585 and q2 = -3.873 gives
    -6.068 +- 0.001 (their rounding), and our exact IK gives -6.0678: the printed
    value is off by more than its rounding, so it is checked against Eq. (8) instead."""
    q_ee = -0.75 * np.pi
    from_table = q_ee - 7.585 - (-3.873)
    assert abs(from_table - (-6.069)) > rounding("-6.069")
    q = Serial3R().inverse_kinematics([-0.5, 0.0, q_ee])
    assert angle_gap(q[2], from_table) <= 2 * rounding("7.585")


@pytest.mark.parametrize("contour", ["zigzag", "diamond"])
def test_parallel_ik_reproduces_table_4_6(contour: str) -> None:
    points, table = PARALLEL_TABLE[contour]
    robot = Parallel5R()
    for j, point in enumerate(points):
        q = robot.inverse_kinematics(point)
        assert np.allclose(robot.forward_kinematics(q), point, atol=1e-12)
        passive, _ = robot.passive_joints(q, np.zeros(2))
        ours = [q[0], q[1], passive[0], passive[1]]  # q1, q2, q3, q4
        for axis in range(4):
            text = table[axis][j]
            assert angle_gap(ours[axis], float(text)) <= rounding(text), (contour, j, axis)


# --------------------------------------------------------------------------- #
# Bad input
# --------------------------------------------------------------------------- #
def test_bad_input_names_the_argument() -> None:
    serial = Serial3R()
    with pytest.raises(InvalidInputError, match=r"q must have 3 entries.*shape \(2,\)"):
        serial.mass_matrix([0.1, 0.2])
    with pytest.raises(InvalidInputError, match="qd must be finite"):
        serial.forward_dynamics([0, 0, 0], [0, np.nan, 0], [0, 0, 0])
    with pytest.raises(InvalidInputError, match="tau must be finite"):
        serial.forward_dynamics([0, 0, 0], [0, 0, 0], [np.inf, 0, 0])
    with pytest.raises(InvalidInputError, match="p must be numeric"):
        serial.inverse_kinematics("far away")
    with pytest.raises(UnreachableError, match=r"outside the serial_3r workspace"):
        serial.inverse_kinematics([2.0, 0.0, 0.0])
    parallel = Parallel5R()
    with pytest.raises(UnreachableError, match=r"parallel_5r workspace: the left \(O1\) chain"):
        parallel.inverse_kinematics([0.5, 0.5])
    short = dataclasses.replace(
        PARALLEL_5R_PARAMS,
        links=PARALLEL_5R_PARAMS.links[:2]
        + tuple(dataclasses.replace(link, length=0.1) for link in PARALLEL_5R_PARAMS.links[2:]),
    )
    with pytest.raises(SingularConfigurationError, match=r"q = \[3.14"):
        Parallel5R(params=short).forward_kinematics([np.pi, 0.0])  # elbows 0.43 m apart > 0.2 m
    assert issubclass(UnreachableError, ValueError)
    with pytest.raises(InvalidInputError, match="unknown robot 'scara'"):
        make_robot("scara")
    with pytest.raises(InvalidInputError, match="tip_mass must be"):
        Serial3R(-1.0)
