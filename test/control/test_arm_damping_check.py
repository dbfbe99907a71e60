"""The stability check with the arm's viscous damping in the plant (issue 50): the held plant against the
damped double integrator's own solution, the map against a step of the loop it models with the plant
integrated finely, no damping giving the undamped map, and ``pdsmc check-gains --realism`` counting the
description's damping and the preset's viscous friction."""

from __future__ import annotations

import numpy as np
import pytest

from pdsmc_ros import cli
from pdsmc_ros.control.lowpass import lowpass_gain
from pdsmc_ros.control.stability import arm_damping, check_gains, held_plant, loop_matrix, rate_margin
from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.runs.builder import make_run


def integrated(mass: np.ndarray, damping: np.ndarray, e: np.ndarray, ed: np.ndarray, a: np.ndarray, h: float,
               steps: int = 2000) -> np.ndarray:
    """``(e, ed)`` after ``h`` of ``edd = -M^-1 B ed + a`` with ``a`` held: RK4 in ``steps`` substeps."""
    d = np.linalg.solve(mass, np.diag(damping))

    def f(x: np.ndarray) -> np.ndarray:
        n = len(e)
        return np.concatenate([x[n:], -d @ x[n:] + a])

    x, dt = np.concatenate([e, ed]), h / steps
    for _ in range(steps):
        k1 = f(x)
        k2 = f(x + dt / 2 * k1)
        k3 = f(x + dt / 2 * k2)
        k4 = f(x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


@pytest.mark.parametrize("h", [1e-3, 0.05, 1.0])
def test_the_held_plant_is_the_damped_joints_own_solution(h: float) -> None:
    """One joint: ``ed(h) = ed e^{-ch} + a (1 - e^{-ch}) / c``, ``e(h)`` its integral (``c = B / M``)."""
    m, b = 0.4, 1.68
    c = b / m
    decay = np.exp(-c * h)
    ad, bd = held_plant(np.array([[m]]), np.array([b]), h)
    assert np.allclose(ad, [[1.0, (1 - decay) / c], [0.0, decay]], rtol=1e-12, atol=1e-15)
    assert np.allclose(bd, [[(h - (1 - decay) / c) / c], [(1 - decay) / c]], rtol=1e-12, atol=1e-15)
    # no damping: the undamped hold, [[1, h], [0, 1]] and [h^2/2, h]
    ad, bd = held_plant(np.array([[m]]), np.array([0.0]), h)
    assert np.allclose(ad, [[1.0, h], [0.0, 1.0]], rtol=0, atol=1e-15) and np.allclose(bd, [[h * h / 2], [h]])


@pytest.mark.parametrize("delay", [0, 2])
def test_the_damped_map_is_one_step_of_the_loop_it_models(delay: int) -> None:
    """x_{k+1} from x_k: the law's command (filtered velocity), delayed, held over a period of the damped
    plant integrated finely; with no damping the map is the undamped one, entry for entry."""
    rng = np.random.default_rng(delay)
    n, h = 2, 1e-3
    mass = np.array([[2.0, 0.3], [0.3, 1.0]])
    kp, kd, cutoff = np.diag([400.0, 300.0]), np.diag([40.0, 20.0]), np.array([100.0, 50.0])
    damping = np.array([9.0, 1.68])
    e, ed, e_prev, v_prev = (rng.normal(size=n) for _ in range(4))
    waiting = [rng.normal(size=n) for _ in range(delay)]
    a = lowpass_gain(h, cutoff)
    v = (1.0 - a) * v_prev + a / h * (e - e_prev)
    command = -np.linalg.solve(mass, kp @ e + kd @ v)
    applied = command if delay == 0 else waiting[-1]
    moved = [command, *waiting[:-1]] if delay else []
    after = np.concatenate([integrated(mass, damping, e, ed, applied, h), e, v, *moved])
    before = np.concatenate([e, ed, e_prev, v_prev, *waiting])
    assert np.allclose(loop_matrix(mass, kp, kd, h, delay, cutoff, damping) @ before, after, rtol=0, atol=1e-9)
    for f in (None, cutoff):
        undamped = loop_matrix(mass, kp, kd, h, delay, f)
        assert np.array_equal(loop_matrix(mass, kp, kd, h, delay, f, np.zeros(n)), undamped)


def test_check_gains_realism_counts_the_arms_viscous_damping(capsys: pytest.CaptureFixture[str]) -> None:
    from pdsmc_ros.sim.mujoco_lockstep import StandIn

    _, bench, _ = StandIn(preset="bench").resolve("ur5", 1000.0)
    delay, cutoff, viscous = bench.loop_terms()
    spec = make_run("ur5", "circle", "pd")
    robot = spec.robot_model()
    assert np.array_equal(arm_damping(robot, viscous), robot.B + viscous) and arm_damping(robot, None) is None
    undamped = check_gains(spec, delay_periods=delay, filter_hz=cutoff)
    damped = check_gains(spec, delay_periods=delay, filter_hz=cutoff, friction_viscous=viscous)
    # the damping acts on the mode the delay and the filter destabilise: the margin grows
    assert damped.rate.margin > undamped.rate.margin and damped.rate.spectral_radius < undamped.rate.spectral_radius
    cli.main(["check-gains", "--robot", "ur5", "--contour", "circle", "--controller", "pd", "--realism", "bench"])
    out = capsys.readouterr().out
    assert "the arm's viscous damping [9, 9, 9, 1.68, 1.68, 1.68] N m s/rad" in out
    assert f"margin x{damped.rate.margin:.2f}" in out
    # without --realism the check is the one it was: no damping
    cli.main(["check-gains", "--robot", "ur5", "--contour", "circle", "--controller", "pd"])
    assert "viscous damping" not in capsys.readouterr().out


def test_a_bad_viscous_friction_is_refused_in_one_line() -> None:
    spec = make_run("ur5", "circle", "pd")
    for bad in ([-1.0], [np.nan], [1.0, 2.0]):
        with pytest.raises(InvalidInputError, match="viscous friction must be 1 or 6 finite numbers >= 0"):
            rate_margin(spec, spec.reference(), friction_viscous=bad)
