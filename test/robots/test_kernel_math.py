"""The compiled small maths written once (robots/kernel_math.py): the Cholesky solve of the chain's
forward dynamics and of inverse kinematics, and the rotation logarithm of task.rotation_log and IK."""

from __future__ import annotations

import numpy as np

from pdsmc_ros.robots.kernel_math import rotation_vector, solve_spd
from pdsmc_ros.robots.task import axis_rotation, rotation_log


def test_solve_spd_solves_the_leading_block_and_refuses_an_indefinite_matrix() -> None:
    rng = np.random.default_rng(27)
    for size in (1, 3, 6):
        a = rng.normal(size=(size, size))
        m = a @ a.T + size * np.eye(size)
        b = rng.normal(size=size)
        padded = np.zeros((8, 8))
        padded[:size, :size] = m
        out = np.zeros(8)
        assert solve_spd(padded, b, out, size)
        np.testing.assert_allclose(out[:size], np.linalg.solve(m, b), rtol=1e-12, atol=1e-12)
    assert not solve_spd(np.array([[1.0, 2.0], [2.0, 1.0]]), np.ones(2), np.zeros(2), 2)


def test_the_rotation_log_inverts_rodrigues_near_zero_in_between_and_near_a_half_turn() -> None:
    rng = np.random.default_rng(3)
    for angle in (0.0, 1e-9, 1e-7, 0.3, 2.0, np.pi - 1e-7, np.pi - 1e-9):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        r = axis_rotation(axis, np.array(angle))
        w = rotation_log(r)
        # within 1e-6 of a half turn the axis comes from r's symmetric part: accurate to O(pi - angle)
        tolerance = 1e-6 if np.pi - angle < 1e-6 else 1e-12
        np.testing.assert_allclose(axis_rotation(w / angle if angle else axis, np.array(np.linalg.norm(w))), r,
                                   atol=tolerance)
        assert abs(np.linalg.norm(w) - angle) < 1e-7
        out = np.empty(3)
        rotation_vector(r, out)
        np.testing.assert_array_equal(out, w)  # the Python entry is the compiled one
