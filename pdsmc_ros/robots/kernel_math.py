"""Small linear algebra and rotations shared by the compiled kernels (numba).

Written once here: the Cholesky solve of the serial chain's forward dynamics
(:mod:`.spatial_dynamics`) and of inverse kinematics' least-squares steps
(:mod:`.ik_kernels`), and the rotation logarithm of :func:`.task.rotation_log` and of
inverse kinematics' orientation error.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def solve_spd(a, b, out, size):  # noqa: ANN001, ANN201
    """Solve ``a x = b`` into ``out`` for the leading ``size`` x ``size`` block of a symmetric
    positive definite ``a`` (Cholesky, ``L`` written over ``a``'s lower triangle).

    Returns False, leaving ``out`` undefined, when ``a`` is not positive definite.
    """
    for i in range(size):
        for j in range(i + 1):
            s = a[i, j]
            for k in range(j):
                s -= a[i, k] * a[j, k]
            if i == j:
                if s <= 0.0:
                    return False
                a[i, i] = math.sqrt(s)
            else:
                a[i, j] = s / a[j, j]
    for i in range(size):
        s = b[i]
        for k in range(i):
            s -= a[i, k] * out[k]
        out[i] = s / a[i, i]
    for i in range(size - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, size):
            s -= a[k, i] * out[k]
        out[i] = s / a[i, i]
    return True
