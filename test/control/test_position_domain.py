"""The position domain laws (pdsmc_ros.control.position_domain): the transformed dynamics against the
time-domain model, the compiled law against a hand computation on the serial arm, its linearisation
against the law itself, the guards of a master at rest or stalled, and the master's choice."""

from __future__ import annotations

import numpy as np
import pytest

from pdsmc_ros.control import ControlLaw, law, law_names
from pdsmc_ros.control.position_domain import (
    SIGMA_DOT_MIN,
    SWITCH_RATIO,
    V_REST,
    V_REST_PRESET,
    error_map,
    transformed_dynamics,
)
from pdsmc_ros.control.stability import check_gains, effective_gains
from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate


@pytest.mark.parametrize("robot", ["serial_3r", "parallel_5r"])
def test_the_transformed_dynamics_give_the_time_domains_torque(robot: str) -> None:
    """The same motion written in the master's position (``q' = qd / qd_m``,
    ``q'' = (qdd - q' qdd_m) / qd_m^2``) gives Eq. (4.1)'s torque of the time-domain model."""
    spec = make_run(robot, "circle", "pdsmc")
    model = spec.robot_model()
    ref = spec.reference().sample(np.linspace(0.5, 3.5, 9))
    checked = 0
    for q, qd, qdd in zip(ref.q, ref.qd, ref.qdd, strict=True):
        m = int(np.argmax(np.abs(qd)))
        rate, accel = qd[m], qdd[m]
        dq = qd / rate
        ddq = (qdd - dq * accel) / rate**2
        assert dq[m] == pytest.approx(1.0) and abs(ddq[m]) < 1e-9  # the master's own: q_m' = 1, q_m'' = 0
        expected = model.inverse_dynamics(q, qd, qdd)
        got = transformed_dynamics(model, q, dq, ddq, rate, accel)
        assert np.allclose(got, expected, rtol=1e-10, atol=1e-10 * np.max(np.abs(expected)))
        checked += 1
    assert checked == 9


def hand_pdsmc_pos(g: np.ndarray, master: int, q: np.ndarray, qd: np.ndarray, q_d: np.ndarray,
                   qd_d: np.ndarray, qdd_d: np.ndarray) -> np.ndarray:
    """The law as docs/explanation/position-domain.md writes it, one joint at a time."""
    kp, kd, ks, lam, phi, v0 = g[0], g[1], g[2], g[3], g[4], g[V_REST, 0]
    v = qd_d[master]
    delta = v * (q[master] - q_d[master]) / (v * v + v0 * v0)
    v_s = v + qdd_d[master] * delta
    sigma_dot = min(max(1.0 + v_s * (qd[master] - v_s) / (v_s**2 + v0**2), SIGMA_DOT_MIN), 1.0 / SIGMA_DOT_MIN)
    tau = np.empty(len(q))
    for i in range(len(q)):
        if i == master:
            e, ed = q_d[i] - q[i], qd_d[i] - qd[i]
        else:
            e = q_d[i] + qd_d[i] * delta + 0.5 * qdd_d[i] * delta**2 - q[i]
            ed = qd_d[i] + qdd_d[i] * delta - qd[i] / sigma_dot
        s = min(max((lam[i] * e + ed) / phi[i], -1.0), 1.0)
        tau[i] = kp[i] * e + kd[i] * ed + ks[i] * s
    return tau


def stiffness_of(g: np.ndarray) -> np.ndarray:
    """Each joint's ``Kp + Ks lambda / phi``, the weight of its speed in the master's choice."""
    return g[0] + g[2] * g[3] / g[4]


@pytest.mark.parametrize("controller", ["pdsmc_pos", "pd_pos"])
def test_the_law_is_its_hand_computation_on_the_serial_arm(controller: str) -> None:
    spec = make_run("serial_3r", "circle", controller)
    g = spec.gains.matrix()
    rng = np.random.default_rng(53)
    ref = spec.reference().sample(rng.uniform(0.3, 3.7, 25))
    for k in range(25):
        control = ControlLaw.from_spec(spec)  # a fresh law: its master is this reference's fastest joint, weighted
        q = ref.q[k] + rng.normal(0, 2e-3, 3)
        qd = ref.qd[k] + rng.normal(0, 2e-2, 3)
        master = int(np.argmax(stiffness_of(g) * np.abs(ref.qd[k])))
        expected = hand_pdsmc_pos(g, master, q, qd, ref.q[k], ref.qd[k], ref.qdd[k])
        got = control.torque(q, qd, ref.q[k], ref.qd[k], ref.qdd[k])
        assert np.allclose(got, expected, rtol=1e-12, atol=1e-12 * np.max(np.abs(expected)))
        assert int(control.state[0, 0]) == master + 1


def test_the_pd_is_the_pdsmc_without_its_switching_term() -> None:
    assert law("pd_pos").gain_names == ("kp", "kd", "v_rest")
    assert law("pdsmc_pos").gain_names == ("kp", "kd", "ks", "lam", "phi", "v_rest")
    pd = make_run("serial_3r", "circle", "pd_pos")
    assert np.all(pd.gains.matrix()[2] == 0.0)  # ks neutral: no switching term
    assert pd.gains["v_rest"] == (V_REST_PRESET,)


def test_the_presets_are_the_time_domain_laws_plus_v0() -> None:
    for time_law, position_law in (("pd", "pd_pos"), ("pdsmc", "pdsmc_pos")):
        assert position_law in law_names()
        time_gains = make_run("parallel_5r", "circle", time_law).gains
        position_gains = make_run("parallel_5r", "circle", position_law).gains
        for name in law(time_law).gain_names:
            assert position_gains[name] == time_gains[name]


def test_a_reference_at_rest_is_the_time_domain_law() -> None:
    """The guard of a master at rest: with the reference still (a goal's start and end, a hold),
    ``delta = 0`` and ``sigma_dot = 1``: the time-domain PD-SMC to the last bit."""
    time_spec = make_run("serial_3r", "circle", "pdsmc")
    spec = make_run("serial_3r", "circle", "pdsmc_pos")
    rng = np.random.default_rng(1)
    q_d = rng.normal(0, 0.5, 3)
    zero = np.zeros(3)
    for _ in range(10):
        q, qd = q_d + rng.normal(0, 1e-2, 3), rng.normal(0, 0.3, 3)
        assert np.array_equal(ControlLaw.from_spec(spec).torque(q, qd, q_d, zero, zero),
                              ControlLaw.from_spec(time_spec).torque(q, qd, q_d, zero, zero))


def test_a_slow_master_goes_smoothly_to_the_time_domain() -> None:
    """As the master's reference speed ``v`` falls below ``v0``, the slaves' shift ``delta`` goes to 0 as
    ``v / v0^2``: the torque tends to the time-domain law's, continuously (no jump at any speed)."""
    time_spec = make_run("serial_3r", "circle", "pdsmc")
    spec = make_run("serial_3r", "circle", "pdsmc_pos")
    q_d, q = np.array([0.3, 1.0, -0.5]), np.array([0.302, 0.999, -0.5005])
    qd, qdd = np.array([0.0, 0.01, 0.0]), np.array([0.5, 0.2, -0.3])
    gaps = []
    for v in (1e-1, 1e-2, 1e-3, 1e-4, 1e-6):
        qd_d = np.array([v, 0.6 * v, -0.4 * v])
        pos = ControlLaw.from_spec(spec).torque(q, qd, q_d, qd_d, qdd)
        gaps.append(np.max(np.abs(pos - ControlLaw.from_spec(time_spec).torque(q, qd, q_d, qd_d, qdd))))
    assert all(b < a for a, b in zip(gaps, gaps[1:], strict=False))
    assert gaps[-1] < 0.02 * gaps[-2]  # linear in v: v 100 times smaller, the gap as much
    assert gaps[-1] < 1e-3  # N m, at 1e-6 rad/s


def test_a_stalled_master_holds_the_slaves_derivative_gain() -> None:
    """The master measured at rest while its reference moves: ``sigma_dot`` is held at
    :data:`SIGMA_DOT_MIN`, so a slave's velocity enters as ``qd_s / 0.8``, not ``qd_s / 0``."""
    spec = make_run("serial_3r", "circle", "pd_pos")
    g = spec.gains.matrix()
    q_d = np.array([0.3, 1.0, -0.5])
    qd_d, qdd = np.array([1.0, 0.5, -0.2]), np.zeros(3)
    base = ControlLaw.from_spec(spec).torque(q_d, np.array([0.0, 0.0, 0.0]), q_d, qd_d, qdd)
    moved = ControlLaw.from_spec(spec).torque(q_d, np.array([0.0, 0.1, 0.0]), q_d, qd_d, qdd)
    assert np.all(np.isfinite(base))
    assert moved[1] - base[1] == pytest.approx(-g[1, 1] * 0.1 / SIGMA_DOT_MIN, rel=1e-12)


def test_the_master_changes_past_the_switch_ratio_only() -> None:
    spec = make_run("serial_3r", "circle", "pdsmc_pos")
    k = stiffness_of(spec.gains.matrix())
    control = ControlLaw.from_spec(spec)
    q, zero = np.zeros(3), np.zeros(3)
    control.torque(q, zero, q, np.array([1.0, 0.5 * k[0] / k[1], 0.0]), zero)
    assert control.state[0, 0] == 1.0  # joint 1, the fastest by its weighted speed
    control.torque(q, zero, q, np.array([1.0, 0.99 * SWITCH_RATIO * k[0] / k[1], 0.0]), zero)
    assert control.state[0, 0] == 1.0  # faster, not by the ratio: kept
    control.torque(q, zero, q, np.array([1.0, 1.01 * SWITCH_RATIO * k[0] / k[1], 0.0]), zero)
    assert control.state[0, 0] == 2.0


def test_a_light_joint_never_masters_a_heavy_one() -> None:
    """The master is chosen by its speed weighted by its stiffness: on the UR5's circle the shoulder pan
    (``Kp`` 2808) masters, not the wrist 3 moving as fast (``Kp`` 43), so no slave feeds back more of the
    master's error than the master itself, and the position domain PD passes the real-time check (x2 with
    two periods of delay; the fastest joint unweighted as master: unstable at any rate)."""
    spec = make_run("ur5", "circle", "pd_pos")
    k = stiffness_of(spec.gains.matrix())
    qd = np.array([-0.548, 0.018, -0.211, 0.193, 0.0, -0.5481])  # the circle at t = 1.667 s: wrist 3 a hair faster
    control = ControlLaw.from_spec(spec)
    q = spec.reference().sample(np.array([1.667])).q[0]
    control.torque(q, np.zeros(6), q, qd, np.zeros(6))
    m = int(control.state[0, 0]) - 1
    assert m == 0
    assert np.all(k * np.abs(qd) <= k[m] * abs(qd[m]))
    assert check_gains(spec, mode="realtime").rate.passes
@pytest.mark.parametrize(("robot", "contour", "at"), [("parallel_5r", "circle", 1.3), ("ur5", "zigzag", 7.333)])
def test_the_linearisation_is_the_laws_own_slope(robot: str, contour: str, at: float) -> None:
    """The stability check's ``(Kp_eff E, Kd_eff E)`` against the compiled law's torque differenced
    at the reference, inside the boundary layer (the UR5's zigzag at 7.333 s: wrist 1 moves fastest, the
    elbow has the largest stiffness-weighted speed: the check's master must be the law's)."""
    spec = make_run(robot, contour, "pdsmc_pos")
    ref = spec.reference().sample(np.array([at]))
    q_d, qd_d, qdd_d = ref.q[0], ref.qd[0], ref.qdd[0]
    mass = spec.robot_model().mass_matrix(q_d)
    kp_eff, kd_eff = effective_gains(spec, mass, qd_d, qdd_d)  # type: ignore[misc]
    n, h = len(q_d), 1e-7
    slope_q, slope_qd = np.empty((n, n)), np.empty((n, n))
    for j in range(n):
        dx = np.zeros(n)
        dx[j] = h
        def tau(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
            return ControlLaw.from_spec(spec).torque(q, qd, q_d, qd_d, qdd_d)
        slope_q[:, j] = (tau(q_d + dx, qd_d) - tau(q_d - dx, qd_d)) / (2 * h)
        slope_qd[:, j] = (tau(q_d, qd_d + dx) - tau(q_d, qd_d - dx)) / (2 * h)
    assert np.allclose(-slope_q, kp_eff, rtol=1e-5, atol=1e-6 * np.max(np.abs(kp_eff)))
    assert np.allclose(-slope_qd, kd_eff, rtol=1e-5, atol=1e-6 * np.max(np.abs(kd_eff)))
    e_map, g_map = error_map(qd_d, qdd_d, V_REST_PRESET, stiffness_of(spec.gains.matrix()))
    assert not np.allclose(e_map, np.eye(n)) and np.any(g_map != 0.0)  # the slaves ignore the master's lag


def test_check_gains_covers_the_position_domain_law() -> None:
    result = check_gains(make_run("parallel_5r", "circle", "pdsmc_pos"), mode="realtime")
    assert result.rate.stable and np.isfinite(result.rate.margin)
    with pytest.raises(InvalidInputError, match="need the reference velocity qd_ref and acceleration qdd_ref"):
        effective_gains(make_run("parallel_5r", "circle", "pdsmc_pos"), np.eye(2))


def test_the_position_domain_shrinks_the_five_bars_ellipse_contour_error() -> None:
    """Measured (docs/explanation/position-domain.md): the horizontal ellipse's mean contour error is
    0.65 of the time-domain PD-SMC's; it must stay below 0.8."""
    time_run = simulate(make_run("parallel_5r", "ellipse_horizontal", "pdsmc"))
    position_run = simulate(make_run("parallel_5r", "ellipse_horizontal", "pdsmc_pos"))
    assert not position_run.diverged
    assert position_run.metrics.contour_mean < 0.8 * time_run.metrics.contour_mean
