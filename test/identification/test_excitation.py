"""The excitation: at rest at home at both ends, within every limit, better conditioned than where its
search started; and the signal chain that turns a recording into the identification's samples."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from pdsmc_ros.errors import InvalidInputError  # noqa: E402
from pdsmc_ros.identification.base import base_parameters  # noqa: E402
from pdsmc_ros.identification.excitation import (  # noqa: E402
    FourierExcitation,
    RestBasis,
    condition_number,
    excitation_limits,
    largest_scale,
    linear_scale,
    optimise_excitation,
)
from pdsmc_ros.identification.model import ArmDynamics, arm_of  # noqa: E402
from pdsmc_ros.identification.signals import (  # noqa: E402
    SLOW_GUARD_PERIODS,
    SLOW_SHARE,
    motion_bandwidth,
    prepare,
)


@pytest.fixture(scope="module")
def twin() -> ArmDynamics:
    return ArmDynamics(arm_of("serial_3r"))


@pytest.fixture(scope="module")
def optimised(twin: ArmDynamics):  # noqa: ANN201
    limits = excitation_limits(twin, excursion=0.8)
    return limits, optimise_excitation(twin, base_parameters(twin), limits, period=4.0, harmonics=4, starts=1,
                                       iterations=15, seed=3)


def test_any_series_of_the_basis_is_at_rest_at_home_at_both_ends() -> None:
    rng = np.random.default_rng(0)
    basis = RestBasis(3, 5)
    home = np.array([0.3, 1.2, -0.5])
    a, b = basis.coefficients(rng.normal(size=basis.size))
    excitation = FourierExcitation(home, a, b, 7.0)
    q, qd, qdd = excitation.sample([0.0, 7.0, 14.0])
    np.testing.assert_allclose(q, np.tile(home, (3, 1)), atol=1e-12)
    np.testing.assert_allclose(qd, 0.0, atol=1e-12)
    np.testing.assert_allclose(qdd, 0.0, atol=1e-12)
    # velocity and acceleration are the derivatives of the position (central differences)
    t = np.linspace(0.5, 6.5, 7)
    h = 1e-5
    plus, minus = excitation.sample(t + h), excitation.sample(t - h)
    np.testing.assert_allclose((plus[0] - minus[0]) / (2 * h), excitation.sample(t)[1], atol=1e-6)
    np.testing.assert_allclose((plus[1] - minus[1]) / (2 * h), excitation.sample(t)[2], atol=1e-5)
    assert excitation.bandwidth == pytest.approx(5 / 7.0)


def test_the_largest_linear_scale_is_exactly_at_a_limit(twin: ArmDynamics) -> None:
    rng = np.random.default_rng(1)
    basis = RestBasis(twin.n, 4)
    a, b = basis.coefficients(rng.normal(size=basis.size))
    shape = FourierExcitation(np.asarray(twin.arm.home, dtype=float), a, b, 4.0)
    limits = excitation_limits(twin, excursion=0.8)
    t = np.arange(800) * 4.0 / 800
    scale = linear_scale(shape, limits, t)
    q, qd, qdd = shape.scaled(scale).sample(t)
    shares = [np.max((q - limits.upper) / (limits.upper - shape.home)), np.max(np.abs(qd) / limits.velocity) - 1.0,
              np.max(np.abs(qdd) / limits.acceleration) - 1.0, np.max((limits.lower - q) / (shape.home - limits.lower))]
    assert max(shares) == pytest.approx(0.0, abs=1e-9)
    assert largest_scale(shape, limits, twin, t) <= scale


def test_the_search_improves_the_condition_and_stays_within_every_limit(twin: ArmDynamics, optimised) -> None:  # noqa: ANN001
    limits, result = optimised
    assert result.condition < result.start_condition
    excitation = result.excitation
    t = np.linspace(0.0, excitation.period, 20001)
    q, qd, qdd = excitation.sample(t)
    assert np.all(q >= limits.lower - 1e-9) and np.all(q <= limits.upper + 1e-9)
    assert np.all(np.abs(qd) <= limits.velocity * (1 + 1e-6))
    assert np.all(np.abs(qdd) <= limits.acceleration * (1 + 1e-6))
    effort = twin.torque(twin.nominal, q[::20], qd[::20], qdd[::20])
    assert np.all(np.abs(effort) <= limits.effort * (1 + 1e-3))
    assert condition_number(twin, base_parameters(twin), excitation) == pytest.approx(result.condition)


def test_the_same_seed_gives_the_same_excitation(twin: ArmDynamics, optimised) -> None:  # noqa: ANN001
    limits, result = optimised
    again = optimise_excitation(twin, base_parameters(twin), limits, period=4.0, harmonics=4, starts=1,
                                iterations=15, seed=3)
    np.testing.assert_array_equal(again.excitation.a, result.excitation.a)


def test_a_home_outside_the_bounds_is_refused(twin: ArmDynamics) -> None:
    limits = excitation_limits(twin, excursion=0.5)
    shifted = type(limits)(limits.lower + 1.0, limits.upper + 1.0, limits.velocity, limits.acceleration,
                           limits.effort)
    with pytest.raises(InvalidInputError, match="home of joint 'joint1'"):
        optimise_excitation(twin, base_parameters(twin), shifted, period=4.0, harmonics=3, starts=1, iterations=1)


def test_filtering_keeps_the_motion_and_finds_its_bandwidth() -> None:
    """A two-harmonic motion recorded at 1 kHz with 1e-5 rad of noise: the bandwidth is its highest
    harmonic, the cut-off five times that, velocities and accelerations those of the motion."""
    rate, f1 = 1000.0, 0.2
    t = np.arange(0.0, 20.0, 1.0 / rate)
    w = 2 * np.pi * f1
    q = np.stack([np.sin(w * t) + 0.3 * np.sin(2 * w * t), 0.5 * np.cos(2 * w * t)], axis=-1)
    qd = np.stack([w * np.cos(w * t) + 0.6 * w * np.cos(2 * w * t), -w * np.sin(2 * w * t)], axis=-1)
    qdd = np.stack([-w**2 * np.sin(w * t) - 1.2 * w**2 * np.sin(2 * w * t), -2 * w**2 * np.cos(2 * w * t)], axis=-1)
    assert motion_bandwidth(q, rate) == pytest.approx(2 * f1, abs=0.05)
    rng = np.random.default_rng(0)
    prepared = prepare(t, q + 1e-5 * rng.normal(size=q.shape), q * 0.0)
    assert prepared.cutoff == pytest.approx(5 * 2 * f1, rel=0.15)
    k = prepared.model_grid[prepared.keep]
    assert np.max(np.abs(prepared.qd[k] - qd[k])) < 2e-3
    assert np.max(np.abs(prepared.qdd[k] - qdd[k])) < 2e-2
    assert prepared.kept_rate == pytest.approx(2.5 * prepared.cutoff, rel=0.1)
    # the dead zone: no kept sample of a joint within a tenth of a cut-off period of its velocity's reversals
    reversal = np.flatnonzero(np.diff(np.sign(qd[:, 1])) != 0)
    near = np.zeros(len(t), dtype=bool)
    for r in reversal:
        width = int(0.1 * rate / prepared.cutoff)
        near[max(r - width + 2, 0): r + width - 1] = True
    assert not np.any(prepared.moving[:, 1][near[k]])
    # kept wherever it is farther than the slow stretches' guard from every instant slower than
    # SLOW_SHARE of its peak speed (test_estimate.py has the guard's own test)
    slow = t[np.abs(qd[:, 1]) < SLOW_SHARE * np.max(np.abs(qd[:, 1]))]
    far = np.min(np.abs(t[k][:, None] - slow[None, :]), axis=1) > 1.1 * SLOW_GUARD_PERIODS / prepared.cutoff
    assert np.count_nonzero(far) >= 10
    assert np.all(prepared.moving[far, 1])


@pytest.mark.parametrize(("args", "message"), [
    (["--robot", "parallel_5r"], "identification needs a serial arm"),
    (["--robot", "serial_3r", "--excursion", "0.1,0.2"], r"--excursion needs one value or 3"),
    (["--robot", "serial_3r", "--periods", "200", "--point-rate", "100"], r"a controller takes at most 5000"),
    (["--robot", "serial_3r", "--share", "1.5"], r"expected a share in \(0, 1\]"),
    (["--robot", "serial_3r", "--harmonics", "1"], "at least 2 harmonics"),
])
def test_excite_refuses_bad_input_in_one_line(tmp_path, capsys, args, message) -> None:  # noqa: ANN001
    """A value the parser refuses exits 2 from argparse, one the command refuses returns 2: one line
    each, nothing written."""
    import re

    from pdsmc_ros.cli import main

    out = tmp_path / "excite"
    try:
        code = main(["excite", *args, "--out", str(out)])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and re.search(message, err[0]), err
    assert not out.exists()
