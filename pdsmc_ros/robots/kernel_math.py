"""Small linear algebra and rotations shared by the compiled kernels (numba).

Written once here: the Cholesky solve of the serial chain's forward dynamics
(:mod:`.spatial_dynamics`) and of inverse kinematics' least-squares steps
(:mod:`.ik_kernels`), and the rotation logarithm of :func:`.task.rotation_log` and of
inverse kinematics' orientation error.
"""

from __future__ import annotations

import math

from numba import njit

from ..kernels.options import ALLOCATION_FREE


@njit(**ALLOCATION_FREE)
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


@njit(**ALLOCATION_FREE)
def rotation_vector(r, out):  # noqa: ANN001, ANN201
    """The rotation vector ``w`` with ``exp([w]x) = r`` (angle in [0, pi]) of a 3 x 3 rotation ``r``
    into ``out`` (:func:`.task.rotation_log` is this, from Python).

    Near 0, ``w = vee(r - r^T) / 2`` (exact to O(angle^3)); near a half turn the axis comes
    from the symmetric part ``(r + I) / 2 = k k^T``, its sign from ``r - r^T``.
    """
    cos = (r[0, 0] + r[1, 1] + r[2, 2] - 1.0) / 2.0
    cos = min(1.0, max(-1.0, cos))
    angle = math.acos(cos)
    sx = r[2, 1] - r[1, 2]
    sy = r[0, 2] - r[2, 0]
    sz = r[1, 0] - r[0, 1]
    if angle < 1e-6:
        out[0], out[1], out[2] = 0.5 * sx, 0.5 * sy, 0.5 * sz
        return
    if math.pi - angle < 1e-6:
        best = 0
        for i in range(1, 3):
            if r[i, i] > r[best, best]:
                best = i
        kx = (r[best, 0] + (1.0 if best == 0 else 0.0)) / 2.0
        ky = (r[best, 1] + (1.0 if best == 1 else 0.0)) / 2.0
        kz = (r[best, 2] + (1.0 if best == 2 else 0.0)) / 2.0
        norm = math.sqrt(kx * kx + ky * ky + kz * kz)
        kx, ky, kz = kx / norm, ky / norm, kz / norm
        if kx * sx + ky * sy + kz * sz < 0.0:
            kx, ky, kz = -kx, -ky, -kz
        out[0], out[1], out[2] = angle * kx, angle * ky, angle * kz
        return
    scale = angle / (2.0 * math.sin(angle))
    out[0], out[1], out[2] = scale * sx, scale * sy, scale * sz


def entry_at(offset: int):  # noqa: ANN201
    """A compiled ``(p, i) -> p[offset + i]``: the ``i``-th of a per-joint block of a flat parameter
    array (a thesis arm's motor inertias and damping, :data:`pdsmc_ros.robots.compiled.COMPILED`)."""

    def entry(p, i):  # noqa: ANN001, ANN202
        return p[offset + i]

    return njit(cache=True, inline="always")(entry)
