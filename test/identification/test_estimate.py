"""Identification on synthetic data with known parameters: exact without noise, within its standard
errors with noise (and the standard errors the spread of repeated estimates), physically consistent
always."""

from __future__ import annotations

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")
pytest.importorskip("clarabel")

from pdsmc_ros.identification.base import base_parameters  # noqa: E402
from pdsmc_ros.identification.consistent import consistent_fit, is_consistent  # noqa: E402
from pdsmc_ros.identification.estimate import (  # noqa: E402
    NotIdentifiableError,
    build_rows,
    check_excitation,
    weighted_least_squares,
)
from pdsmc_ros.identification.excitation import (  # noqa: E402
    FourierExcitation,
    RestBasis,
    excitation_limits,
    largest_scale,
)
from pdsmc_ros.identification.model import ArmDynamics, arm_of  # noqa: E402


@pytest.fixture(scope="module")
def ur5() -> ArmDynamics:
    return ArmDynamics(arm_of("ur5"))


def motion(dynamics: ArmDynamics, seed: int = 0, seconds: float = 30.0, rate: float = 20.0):  # noqa: ANN201
    """A random Fourier excitation within the limits (no search: the tests need a motion, not the best)."""
    rng = np.random.default_rng(seed)
    basis = RestBasis(dynamics.n, 5)
    a, b = basis.coefficients(rng.normal(size=basis.size))
    shape = FourierExcitation(np.asarray(dynamics.arm.home, dtype=float), a, b, 10.0)
    limits = excitation_limits(dynamics, excursion=0.6)
    grid = np.arange(400) * 10.0 / 400
    excitation = shape.scaled(largest_scale(shape, limits, dynamics, grid))
    return excitation.sample(np.arange(int(seconds * rate)) / rate)


def truth_of(dynamics: ArmDynamics) -> np.ndarray:
    layout = dynamics.layout
    truth = dynamics.nominal.copy()
    truth[layout.payload] = pin.Inertia(2.0, np.array([0.01, -0.02, 0.05]), np.diag([1e-3, 1e-3, 1e-3])
                                        ).toDynamicParameters()
    truth[layout.joint_field("armature")] = [0.3, 0.3, 0.2, 0.05, 0.05, 0.05]
    truth[layout.joint_field("friction_coulomb")] = [5.0, 7.0, 4.0, 1.2, 1.0, 0.6]
    truth[layout.joint_field("friction_viscous")] = [2.0, 3.0, 1.5, 0.4, 0.35, 0.25]
    return truth


def fit(dynamics: ArmDynamics, q, qd, qdd, tau):  # noqa: ANN001, ANN201
    base = base_parameters(dynamics)
    rows = build_rows(dynamics, q, qd, qdd, tau, np.abs(qd) > 1e-6)
    check_excitation(dynamics, base, rows, q)
    estimate = weighted_least_squares(base, rows, dynamics.n)
    return base, estimate, consistent_fit(dynamics, base, estimate)


def test_exact_without_noise(ur5: ArmDynamics) -> None:
    """The URDF's links, an unknown 2 kg payload, motor inertia and friction: every base parameter to
    1e-9 of its size, and the payload, armature and frictions themselves to 1e-6 (the links are the
    URDF's: the fit's prior is right where the data do not decide)."""
    q, qd, qdd = motion(ur5)
    truth = truth_of(ur5)
    base, estimate, result = fit(ur5, q, qd, qdd, ur5.torque(truth, q, qd, qdd))
    expected = base.of(truth)
    scale = np.maximum(np.abs(expected), 1e-3)
    assert np.max(np.abs(estimate.values - expected) / scale) < 1e-9
    assert not result.projected
    assert np.all(is_consistent(result.values, ur5))
    layout = ur5.layout
    for part in (layout.payload, layout.joint_field("armature"), layout.joint_field("friction_coulomb"),
                 layout.joint_field("friction_viscous")):
        np.testing.assert_allclose(result.values[part], truth[part], atol=1e-6 * max(1.0, np.abs(truth[part]).max()))
    np.testing.assert_allclose(base.of(result.values), expected, atol=1e-7 * np.abs(expected).max())


def test_exact_base_parameters_when_the_links_differ_from_the_urdf(ur5: ArmDynamics) -> None:
    """Links 20 % heavier than the URDF says (a consistent body each): the base parameters are still
    exact, and the consistent fit keeps them (what the torques can tell)."""
    layout = ur5.layout
    truth = truth_of(ur5)
    truth[layout.links] *= 1.2
    q, qd, qdd = motion(ur5, seed=1)
    base, estimate, result = fit(ur5, q, qd, qdd, ur5.torque(truth, q, qd, qdd))
    expected = base.of(truth)
    np.testing.assert_allclose(estimate.values, expected, atol=1e-9 * np.abs(expected).max())
    np.testing.assert_allclose(base.of(result.values), expected, atol=1e-7 * np.abs(expected).max())
    assert np.all(is_consistent(result.values, ur5))
    np.testing.assert_allclose(ur5.consistent_torque(result.values, q, qd, qdd), ur5.torque(truth, q, qd, qdd),
                               atol=1e-6)


NOISE = np.array([0.5, 0.5, 0.5, 0.05, 0.05, 0.05])
"""Effort noise per joint (N m): a fiftieth to a third of what the joints need here."""


def test_within_its_standard_errors_with_noise(ur5: ArmDynamics) -> None:
    q, qd, qdd = motion(ur5, seed=2)
    truth = truth_of(ur5)
    tau = ur5.torque(truth, q, qd, qdd)
    rng = np.random.default_rng(3)
    base, estimate, result = fit(ur5, q, qd, qdd, tau + NOISE * rng.normal(size=tau.shape))
    z = (estimate.values - base.of(truth)) / estimate.standard_errors
    assert np.mean(np.abs(z) < 3.0) >= 0.95, np.round(z, 2)
    assert np.all(np.abs(z) < 4.5)
    # the residual's spread is the noise's
    np.testing.assert_allclose(estimate.sigma, NOISE, rtol=0.15)
    layout = ur5.layout
    for part in (layout.payload.start, *range(layout.joint_field("friction_coulomb").start,
                                              layout.joint_field("friction_viscous").stop)):
        assert abs(result.values[part] - truth[part]) < 3.5 * result.standard_errors[part], layout.names[part]
    assert np.all(is_consistent(result.values, ur5))


def test_the_standard_errors_are_the_spread_of_repeated_estimates(ur5: ArmDynamics) -> None:
    """Twenty noise draws on one motion: each parameter's spread of estimates is its standard error
    (within what twenty draws can tell: a factor 0.6 to 1.5)."""
    q, qd, qdd = motion(ur5, seed=4)
    truth = truth_of(ur5)
    tau = ur5.torque(truth, q, qd, qdd)
    base = base_parameters(ur5)
    rng = np.random.default_rng(5)
    values, errors = [], []
    for _ in range(20):
        rows = build_rows(ur5, q, qd, qdd, tau + NOISE * rng.normal(size=tau.shape), np.abs(qd) > 1e-6)
        estimate = weighted_least_squares(base, rows, ur5.n)
        values.append(estimate.values)
        errors.append(estimate.standard_errors)
    ratio = np.std(values, axis=0, ddof=1) / np.mean(errors, axis=0)
    assert 0.6 < np.median(ratio) < 1.5 and np.all((ratio > 0.3) & (ratio < 2.2)), np.round(ratio, 2)


def test_an_impossible_estimate_is_moved_to_the_nearest_consistent_one(ur5: ArmDynamics) -> None:
    """No friction and no motor inertia in truth, heavy noise: the least-squares estimate has negative
    ones; the fit has none, every link is a body, and its base parameters stay within a few of the
    estimate's standard errors."""
    layout = ur5.layout
    truth = ur5.nominal.copy()
    q, qd, qdd = motion(ur5, seed=6, seconds=20.0)
    tau = ur5.torque(truth, q, qd, qdd)
    rng = np.random.default_rng(7)
    base, estimate, result = fit(ur5, q, qd, qdd, tau + 4.0 * NOISE * rng.normal(size=tau.shape))
    friction = [k for k in base.independent if layout.names[k].startswith(("friction", "armature"))]
    assert np.any(estimate.values[np.isin(base.independent, friction)] < 0.0)
    assert result.projected
    assert np.all(is_consistent(result.values, ur5))
    assert np.all(result.values[layout.joint_field("friction_coulomb")] >= -1e-9)
    moved = (base.of(result.values) - estimate.values) / estimate.standard_errors
    assert np.max(np.abs(moved)) < 5.0


def test_the_thesis_arms_impossible_urdf_links_come_out_as_bodies() -> None:
    """serial_3r's URDF links violate the triangle inequality (a placeholder out-of-plane inertia): the
    fit makes them bodies without changing a torque."""
    twin = ArmDynamics(arm_of("serial_3r"))
    truth = twin.nominal.copy()
    truth[twin.layout.joint_field("friction_viscous")] = [0.5, 0.3, 0.2]
    q, qd, qdd = motion(twin, seed=8)
    _, _, result = fit(twin, q, qd, qdd, twin.torque(truth, q, qd, qdd))
    assert np.all(is_consistent(result.values, twin))
    np.testing.assert_allclose(twin.consistent_torque(result.values, q, qd, qdd), twin.torque(truth, q, qd, qdd),
                               atol=1e-6)


def test_a_joint_that_never_moves_is_named(ur5: ArmDynamics) -> None:
    q, qd, qdd = motion(ur5, seed=9)
    q[:, 0] = q[0, 0]
    qd[:, 0] = 0.0
    qdd[:, 0] = 0.0
    tau = ur5.torque(truth_of(ur5), q, qd, qdd)
    with pytest.raises(NotIdentifiableError, match=r"not exciting enough.*shoulder_pan_joint did not move"):
        fit(ur5, q, qd, qdd, tau)


def test_too_few_samples_is_too_short(ur5: ArmDynamics) -> None:
    q, qd, qdd = motion(ur5, seconds=1.0, rate=20.0)
    with pytest.raises(NotIdentifiableError, match="run too short"):
        fit(ur5, q, qd, qdd, ur5.torque(truth_of(ur5), q, qd, qdd))


def test_the_motion_bandwidth_is_read_above_an_encoders_white_floor() -> None:
    """A 0.5 Hz motion read by an 18-bit encoder with half a count of noise at 1 kHz: the quantised
    positions' white floor, weighed by f^2, holds 0.4 % of the velocities' energy near the Nyquist
    frequency; the bandwidth is still the motion's (its highest harmonic, to a line of the spectrum)."""
    from pdsmc_ros.identification.signals import motion_bandwidth

    rate, seconds = 1000.0, 40.0
    t = np.arange(0.0, seconds, 1.0 / rate)
    rng = np.random.default_rng(3)
    q = np.zeros((len(t), 3))
    for j in range(3):
        for h in range(1, 6):
            q[:, j] += rng.uniform(0.02, 0.1) * np.sin(2.0 * np.pi * 0.1 * h * t + rng.uniform(0, 2 * np.pi))
    exact = motion_bandwidth(q, rate)
    grid = 2.0 * np.pi / 2**18
    read = np.round((q + 0.5 * grid * rng.standard_normal(q.shape)) / grid) * grid
    assert exact == pytest.approx(0.5, abs=0.05)
    assert motion_bandwidth(read, rate) == pytest.approx(exact, abs=0.05)


def test_a_slow_joint_is_in_the_dead_zone() -> None:
    """Where a joint is slower than SLOW_SHARE of its peak speed its equations are left out (it may
    stick there), and within SLOW_GUARD_PERIODS of the cut-off of such a stretch (the filter's
    reach); elsewhere, away from reversals, they are kept."""
    from pdsmc_ros.identification.signals import SLOW_GUARD_PERIODS, SLOW_SHARE, prepare

    rate = 500.0
    t = np.arange(0.0, 30.0, 1.0 / rate)
    q = np.stack([0.3 * np.sin(2.0 * np.pi * 0.2 * t), 0.2 * np.sin(2.0 * np.pi * 0.3 * t + 0.5)], axis=1)
    prepared = prepare(t, q, np.zeros_like(q), cutoff=2.0)
    _, qd, _ = prepared.kept_motion()
    slow = np.abs(qd) < SLOW_SHARE * np.max(np.abs(qd), axis=0)
    assert np.any(slow)
    assert not np.any(prepared.moving[slow])
    guard = SLOW_GUARD_PERIODS / prepared.cutoff
    assert guard > 0.0
    # each kept sample's time to the nearest slow instant of the recording, per joint
    slow_at = np.abs(prepared.qd) < SLOW_SHARE * np.max(np.abs(qd), axis=0)
    distance = np.stack([np.min(np.abs(prepared.t[:, None] - prepared.grid[slow_at[:, j]][None, :]), axis=1)
                         for j in range(q.shape[1])], axis=1)
    assert not np.any(prepared.moving[distance < 0.9 * guard])
    far = distance > 1.1 * guard
    assert np.count_nonzero(far) >= 10
    assert np.mean(prepared.moving[far]) > 0.9


def test_static_friction_at_rest_is_a_set_through_the_filters() -> None:
    """A joint that sticks and breaks away, read by an 18-bit encoder with half a count of noise, its
    effort Coulomb friction alone: ``fc sign(qd)`` while it moves, and while it is stuck whatever
    torque within ``+/- fc`` (here a random level per stretch, ramping to ``fc`` before breakaway).
    Filtered as the efforts are, that effort lies within the set ``fc (centre +/- radius)`` of
    Prepared.static_friction_set at every kept sample, and not within that set's radius held to 1; the
    point ``fc sign(qd)`` misses it by a tenth of ``fc`` and more, and a torque of 1.5 fc while stuck
    (outside the law) falls outside the set."""
    from pdsmc_ros.identification.signals import prepare

    rate, fc = 1000.0, 6.0
    rng = np.random.default_rng(5)
    pieces_v, pieces_f = [], []
    direction = 1.0
    for _ in range(12):
        rest = int(rng.uniform(0.4, 1.2) * rate)
        level = rng.uniform(-1.0, 1.0)
        ramp = np.clip(np.linspace(-1.0, 1.0, rest) * 4.0, 0.0, 1.0)  # to fc * direction in the last quarter
        pieces_f.append(fc * (level + (direction - level) * ramp))
        pieces_v.append(np.zeros(rest))
        move = int(rng.uniform(0.8, 1.6) * rate)
        pieces_v.append(direction * 0.3 * np.sin(np.pi * np.arange(1, move + 1) / (move + 1)) ** 2)
        pieces_f.append(np.full(move, fc * direction))
        direction = -direction
    velocity, friction = np.concatenate(pieces_v), np.concatenate(pieces_f)
    t = np.arange(len(velocity)) / rate
    q = np.cumsum(velocity) / rate
    grid = 2.0 * np.pi / 2**18
    read = np.round((q + 0.5 * grid * rng.standard_normal(q.shape)) / grid) * grid
    prepared = prepare(t, read[:, None], friction[:, None], cutoff=13.0)
    centre, radius = prepared.static_friction_set()
    assert 0.2 < np.mean(prepared.rest) < 0.6
    outside = np.abs(prepared.tau - np.clip(prepared.tau, fc * (centre - radius), fc * (centre + radius)))
    assert np.max(outside) < 1e-3 * fc
    # the filter's negative lobes: a set held within +/- fc (its radius clipped to 1) misses by 6 % of fc
    narrow = np.minimum(radius, 1.0)
    missed = np.abs(prepared.tau - np.clip(prepared.tau, fc * (centre - narrow), fc * (centre + narrow)))
    assert np.max(missed) > 0.03 * fc
    point = fc * prepared.stepped(np.sign(prepared.qd))
    assert np.max(np.abs(prepared.tau - point)) > 0.1 * fc
    held_too_hard = np.where(velocity == 0.0, 1.5 * fc * np.sign(friction + 1e-9), friction)
    wrong = prepare(t, read[:, None], held_too_hard[:, None], cutoff=13.0)
    outside = np.abs(wrong.tau - np.clip(wrong.tau, fc * (centre - radius), fc * (centre + radius)))
    assert np.max(outside) > 0.2 * fc


def test_the_rest_windows_slope_noise_is_the_band_over_stick_sigmas() -> None:
    """rest_window's line fit has a slope noise of at most band / STICK_SIGMAS, and one sample fewer
    on each side would exceed it (measured on white noise, 4,000 windows)."""
    from pdsmc_ros.identification.signals import STICK_SIGMAS, rest_window

    rate, sigma, band = 1000.0, 1.5e-5, 5.5e-4
    count = rest_window(np.array([sigma]), np.array([band]), rate)
    assert count % 2 == 1

    def slope_std(n: int) -> float:
        return sigma * rate / np.sqrt(n * (n * n - 1) / 12.0)

    assert slope_std(count) <= band / STICK_SIGMAS < slope_std(count - 2)
    rng = np.random.default_rng(2)
    x = (np.arange(count) - (count - 1) / 2) / rate
    slopes = (sigma * rng.standard_normal((4000, count))) @ x / (x @ x)
    assert np.std(slopes) == pytest.approx(slope_std(count), rel=0.05)
