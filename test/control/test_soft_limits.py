"""The controller's output limits: ros2_control's soft limits of an effort command (issue 37).

The kernel (:func:`pdsmc_ros.control.soft_limits.soft_limit`) against the rule re-stated from
ros2_control's ``joint_limits`` (ROS 1's ``EffortJointSoftLimitsHandle::enforceLimits``), its
boundary cases, ``np.clip`` where limits are unknown, and a closed loop that it keeps below the
arm's velocity limit where the bare law drives far past it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pdsmc_ros.control import ControlLaw
from pdsmc_ros.control.soft_limits import (
    SOFT_VELOCITY_BAND,
    effort_only_table,
    robot_soft_limits,
    soft_limit,
    soft_limit_table,
)
from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.robots.catalog import resolve_robot
from pdsmc_ros.robots.registry import make_robot
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim.loop import run_loop


def clamp(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi)


def reference_rule(cmd: float, pos: float, vel: float, e_max: float, v_max: float, lower: float, upper: float,
                   k_position: float, k_velocity: float) -> float:
    """``EffortJointSoftLimitsHandle::enforceLimits`` (ros_control joint_limits_interface), written
    out from its C++ independently of the kernel: soft position limits = the limits given."""
    if math.isfinite(lower) or math.isfinite(upper):
        soft_min_vel = clamp(-k_position * (pos - lower), -v_max, v_max) if math.isfinite(lower) else -v_max
        soft_max_vel = clamp(-k_position * (pos - upper), -v_max, v_max) if math.isfinite(upper) else v_max
    else:
        soft_min_vel, soft_max_vel = -v_max, v_max
    soft_min_eff = clamp(-k_velocity * (vel - soft_min_vel), -e_max, e_max)
    soft_max_eff = clamp(-k_velocity * (vel - soft_max_vel), -e_max, e_max)
    return clamp(cmd, soft_min_eff, soft_max_eff)


finite = st.floats(-1e3, 1e3, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(cmd=finite, pos=st.floats(-4.0, 4.0), vel=st.floats(-10.0, 10.0), e_max=st.floats(0.1, 200.0),
       v_max=st.floats(0.1, 5.0), lower=st.floats(-3.0, 0.0), width=st.floats(0.1, 4.0),
       k_position=st.floats(0.0, 100.0), k_velocity=st.floats(0.01, 1e3))
def test_the_ros2_control_rule(cmd: float, pos: float, vel: float, e_max: float, v_max: float, lower: float,
                               width: float, k_position: float, k_velocity: float) -> None:
    upper = lower + width
    table = soft_limit_table(np.array([e_max]), np.array([v_max]), np.array([[lower, upper]]),
                             k_position=k_position, k_velocity=np.array([k_velocity]))
    tau = np.array([cmd])
    counts = np.zeros(1, dtype=np.int64)
    changed = soft_limit(tau, np.array([pos]), np.array([vel]), table, counts, 1)
    v_soft = (1.0 - SOFT_VELOCITY_BAND) * v_max  # the soft velocity limit, below the arm's
    expected = reference_rule(cmd, pos, vel, e_max, v_soft, lower, upper, k_position, k_velocity)
    assert tau[0] == expected
    assert changed == int(expected != cmd)
    assert counts[0] == int(abs(expected) >= e_max)  # saturated: at the effort limit


@settings(max_examples=200, deadline=None)
@given(tau=st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=3, max_size=3),
       limit=st.lists(st.floats(0.0, 1e3), min_size=3, max_size=3),
       qd=st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3))
def test_unknown_limits_are_a_plain_clip(tau: list[float], limit: list[float], qd: list[float]) -> None:
    """No velocity or position limit known: ``np.clip`` float for float (the thesis runs' clamp)."""
    got = np.array(tau)
    soft_limit(got, np.zeros(3), np.array(qd), effort_only_table(np.array(limit), 3), np.zeros(3, dtype=np.int64), 1)
    assert got.tolist() == np.clip(tau, -np.array(limit), np.array(limit)).tolist()


def test_the_velocity_bound() -> None:
    """Default gains: the whole effort up to 90 % of the velocity limit, none that pushes faster at
    90 %, a full braking effort at the limit; braking is never cut."""
    table = soft_limit_table(np.array([100.0]), np.array([2.0]), np.array([[-np.inf, np.inf]]))
    assert table[5, 0] == pytest.approx(100.0 / (SOFT_VELOCITY_BAND * 2.0))

    def limited(cmd: float, vel: float) -> float:
        tau = np.array([cmd])
        soft_limit(tau, np.zeros(1), np.array([vel]), table, np.zeros(1, dtype=np.int64), 1)
        return float(tau[0])

    assert limited(100.0, 1.6) == pytest.approx(100.0)
    assert limited(100.0, 1.7) == pytest.approx(50.0)
    assert limited(100.0, 1.8) == pytest.approx(0.0, abs=1e-9)
    assert limited(100.0, 2.0) == pytest.approx(-100.0)  # at the limit: full braking
    assert limited(-100.0, 2.5) == -100.0  # braking is never cut


def test_the_position_bound() -> None:
    """Toward a position limit the allowed velocity shrinks with the distance; beyond it the effort
    pushes back."""
    table = soft_limit_table(np.array([100.0]), np.array([2.0]), np.array([[-1.0, 1.0]]), k_position=10.0)

    def bounds(pos: float, vel: float) -> tuple[float, float]:
        lo, hi = np.array([-1e9]), np.array([1e9])
        zero = np.zeros(1, dtype=np.int64)
        soft_limit(lo, np.array([pos]), np.array([vel]), table, zero, 1)
        soft_limit(hi, np.array([pos]), np.array([vel]), table, zero, 1)
        return float(lo[0]), float(hi[0])

    assert bounds(0.0, 0.0) == (-100.0, 100.0)
    lo, hi = bounds(0.95, 0.5)  # 0.05 rad from the upper limit: 0.5 rad/s allowed toward it
    assert hi == pytest.approx(0.0, abs=1e-9) and lo == -100.0
    lo, hi = bounds(1.05, 0.0)  # beyond it: only efforts back toward the range
    assert hi < 0.0 and lo == -100.0


def test_bad_gains_are_refused() -> None:
    with pytest.raises(InvalidInputError, match="k_position"):
        soft_limit_table(np.ones(2), np.ones(2), np.zeros((2, 2)), k_position=-1.0)
    with pytest.raises(InvalidInputError, match="k_velocity must be 2"):
        soft_limit_table(np.ones(2), np.ones(2), np.zeros((2, 2)), k_velocity=np.array([1.0, np.nan]))


def test_a_step_stays_below_the_velocity_limit() -> None:
    """The UR5 in the compiled loop with PD and a 1.5 rad step on every joint: the bare law drives the
    joints far past their velocity limits; with the soft limits no joint passes its limit by more
    than the one period a sampled loop needs to react."""
    robot = make_robot(resolve_robot("ur5"))
    spec = make_run("ur5", "circle", "pd", rate=1000.0)
    q0 = robot.home_configuration()
    steps = 2000
    refs = np.zeros((steps + 1, 3, robot.n))
    refs[:, 0] = q0 + 1.5
    h = 1.0 / spec.rate
    _, qd_free, _, _ = run_loop(robot, ControlLaw.from_spec(spec), q0, refs, h, 1,
                                effort_only_table(robot.effort_limits, robot.n))
    soft = robot_soft_limits(robot, q0, spec.rate)
    _, qd_soft, _, outcome = run_loop(robot, ControlLaw.from_spec(spec), q0, refs, h, 1, soft)
    ratio_free = np.nanmax(np.abs(qd_free) / robot.velocity_limits)
    ratio_soft = np.nanmax(np.abs(qd_soft) / robot.velocity_limits)
    assert ratio_free > 1.5  # what the soft limits are for
    assert ratio_soft <= 1.0, ratio_soft
    assert sum(outcome.saturated) > 0
