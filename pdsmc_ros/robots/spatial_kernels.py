"""Kinematics of the packed serial chain, compiled (numba): the pose of every joint, and the
end effector's position, pose, task-plane point and Jacobian.

``p`` is :func:`.spatial_layout.pack`'s flat array; :func:`kinematics_pass` fills the
scratch ``work`` with each joint's motion subspace (and, for the dynamics of
:mod:`.spatial_dynamics`, each body's first moment and inertia) in base coordinates.
"""

from __future__ import annotations

import math

from numba import njit

from ..kernels.options import ALLOCATION_FREE
from .spatial_layout import (
    EE_JOINT,
    EE_ROTATION,
    EE_TRANSLATION,
    HEADER_SIZE,
    J_AXIS,
    J_INERTIA,
    J_KIND,
    J_LEVER,
    J_MASS,
    J_ROTATION,
    J_TRANSLATION,
    JOINT_SIZE,
    N_JOINTS,
    PLANE_ORIGIN,
    PLANE_U,
    PLANE_V,
    REVOLUTE,
    W_H,
    W_IO,
    W_S,
    WORK_STRIDE,
    cross,
)


# --------------------------------------------------------------------------- #
# Passes
# --------------------------------------------------------------------------- #
@njit(**ALLOCATION_FREE)
def kinematics_pass(p, q, work, level):  # noqa: ANN001, ANN202
    """Kinematics in base coordinates into ``work``.

    For each joint ``k``: its motion subspace ``S`` (always); with ``level >= 1``
    its body's first moment ``m c``; with ``level >= 2`` the body's rotational
    inertia about the base origin. The pose of the end-effector's parent joint
    goes to ``work[n * WORK_STRIDE:][:12]`` (rotation row-major, then origin).
    """
    n = int(p[N_JOINTS])
    jee = int(p[EE_JOINT])
    pose = n * WORK_STRIDE
    # the running pose of joint k's parent in the base: rotation r, origin (px, py, pz)
    r00, r01, r02 = 1.0, 0.0, 0.0
    r10, r11, r12 = 0.0, 1.0, 0.0
    r20, r21, r22 = 0.0, 0.0, 1.0
    px, py, pz = 0.0, 0.0, 0.0
    for k in range(-1, n):  # k = -1 is the base itself, for a frame fixed to it
        if k >= 0:
            b = HEADER_SIZE + k * JOINT_SIZE
            e = b + J_ROTATION
            # the joint frame at q = 0: r_e = r E, origin moved by r t
            e00, e01, e02 = p[e], p[e + 1], p[e + 2]
            e10, e11, e12 = p[e + 3], p[e + 4], p[e + 5]
            e20, e21, e22 = p[e + 6], p[e + 7], p[e + 8]
            t = b + J_TRANSLATION
            tx, ty, tz = p[t], p[t + 1], p[t + 2]
            px, py, pz = (px + r00 * tx + r01 * ty + r02 * tz,
                          py + r10 * tx + r11 * ty + r12 * tz,
                          pz + r20 * tx + r21 * ty + r22 * tz)
            b00 = r00 * e00 + r01 * e10 + r02 * e20
            b01 = r00 * e01 + r01 * e11 + r02 * e21
            b02 = r00 * e02 + r01 * e12 + r02 * e22
            b10 = r10 * e00 + r11 * e10 + r12 * e20
            b11 = r10 * e01 + r11 * e11 + r12 * e21
            b12 = r10 * e02 + r11 * e12 + r12 * e22
            b20 = r20 * e00 + r21 * e10 + r22 * e20
            b21 = r20 * e01 + r21 * e11 + r22 * e21
            b22 = r20 * e02 + r21 * e12 + r22 * e22
            ax, ay, az = p[b + J_AXIS], p[b + J_AXIS + 1], p[b + J_AXIS + 2]
            # the axis in the base: the joint's own motion leaves it fixed
            zx = b00 * ax + b01 * ay + b02 * az
            zy = b10 * ax + b11 * ay + b12 * az
            zz = b20 * ax + b21 * ay + b22 * az
            s = k * WORK_STRIDE + W_S
            qk = q[k]
            if p[b + J_KIND] == REVOLUTE:
                c = math.cos(qk)
                sn = math.sin(qk)
                v = 1.0 - c
                # Rodrigues: rot(a, q) = c I + sin [a]x + (1 - c) a a^T
                j00 = c + v * ax * ax
                j11 = c + v * ay * ay
                j22 = c + v * az * az
                j01 = v * ax * ay - sn * az
                j10 = v * ax * ay + sn * az
                j02 = v * ax * az + sn * ay
                j20 = v * ax * az - sn * ay
                j12 = v * ay * az - sn * ax
                j21 = v * ay * az + sn * ax
                r00 = b00 * j00 + b01 * j10 + b02 * j20
                r01 = b00 * j01 + b01 * j11 + b02 * j21
                r02 = b00 * j02 + b01 * j12 + b02 * j22
                r10 = b10 * j00 + b11 * j10 + b12 * j20
                r11 = b10 * j01 + b11 * j11 + b12 * j21
                r12 = b10 * j02 + b11 * j12 + b12 * j22
                r20 = b20 * j00 + b21 * j10 + b22 * j20
                r21 = b20 * j01 + b21 * j11 + b22 * j21
                r22 = b20 * j02 + b21 * j12 + b22 * j22
                # rotation about z through the joint origin: velocity p x z at the base origin
                lx, ly, lz = cross(px, py, pz, zx, zy, zz)
                work[s], work[s + 1], work[s + 2] = lx, ly, lz
                work[s + 3], work[s + 4], work[s + 5] = zx, zy, zz
            else:
                r00, r01, r02 = b00, b01, b02
                r10, r11, r12 = b10, b11, b12
                r20, r21, r22 = b20, b21, b22
                px += zx * qk
                py += zy * qk
                pz += zz * qk
                work[s], work[s + 1], work[s + 2] = zx, zy, zz
                work[s + 3], work[s + 4], work[s + 5] = 0.0, 0.0, 0.0
            if level >= 1:
                m = p[b + J_MASS]
                lv = b + J_LEVER
                lx, ly, lz = p[lv], p[lv + 1], p[lv + 2]
                cx = px + r00 * lx + r01 * ly + r02 * lz
                cy = py + r10 * lx + r11 * ly + r12 * lz
                cz = pz + r20 * lx + r21 * ly + r22 * lz
                h = k * WORK_STRIDE + W_H
                work[h], work[h + 1], work[h + 2] = m * cx, m * cy, m * cz
                if level >= 2:
                    i = b + J_INERTIA
                    ixx, iyy, izz = p[i], p[i + 1], p[i + 2]
                    ixy, ixz, iyz = p[i + 3], p[i + 4], p[i + 5]
                    # rows of r I_c, then (r I_c r^T)_ij = row_i . r_j (symmetric: six entries)
                    t00 = r00 * ixx + r01 * ixy + r02 * ixz
                    t01 = r00 * ixy + r01 * iyy + r02 * iyz
                    t02 = r00 * ixz + r01 * iyz + r02 * izz
                    t10 = r10 * ixx + r11 * ixy + r12 * ixz
                    t11 = r10 * ixy + r11 * iyy + r12 * iyz
                    t12 = r10 * ixz + r11 * iyz + r12 * izz
                    t20 = r20 * ixx + r21 * ixy + r22 * ixz
                    t21 = r20 * ixy + r21 * iyy + r22 * iyz
                    t22 = r20 * ixz + r21 * iyz + r22 * izz
                    # parallel axis theorem to the base origin: + m (|c|^2 1 - c c^T)
                    o = k * WORK_STRIDE + W_IO
                    work[o] = t00 * r00 + t01 * r01 + t02 * r02 + m * (cy * cy + cz * cz)
                    work[o + 1] = t10 * r10 + t11 * r11 + t12 * r12 + m * (cx * cx + cz * cz)
                    work[o + 2] = t20 * r20 + t21 * r21 + t22 * r22 + m * (cx * cx + cy * cy)
                    work[o + 3] = t00 * r10 + t01 * r11 + t02 * r12 - m * cx * cy
                    work[o + 4] = t00 * r20 + t01 * r21 + t02 * r22 - m * cx * cz
                    work[o + 5] = t10 * r20 + t11 * r21 + t12 * r22 - m * cy * cz
        if k + 1 == jee:
            work[pose], work[pose + 1], work[pose + 2] = r00, r01, r02
            work[pose + 3], work[pose + 4], work[pose + 5] = r10, r11, r12
            work[pose + 6], work[pose + 7], work[pose + 8] = r20, r21, r22
            work[pose + 9], work[pose + 10], work[pose + 11] = px, py, pz


@njit(**ALLOCATION_FREE)
def _ee_origin(p, work):  # noqa: ANN001, ANN202
    """The end-effector's origin in the base from its parent joint's pose (after :func:`kinematics_pass`)."""
    o = int(p[N_JOINTS]) * WORK_STRIDE
    tx, ty, tz = p[EE_TRANSLATION], p[EE_TRANSLATION + 1], p[EE_TRANSLATION + 2]
    return (work[o + 9] + work[o] * tx + work[o + 1] * ty + work[o + 2] * tz,
            work[o + 10] + work[o + 3] * tx + work[o + 4] * ty + work[o + 5] * tz,
            work[o + 11] + work[o + 6] * tx + work[o + 7] * ty + work[o + 8] * tz)


@njit(**ALLOCATION_FREE)
def ee_position(p, q, out, work):  # noqa: ANN001, ANN201
    """End-effector position in the base frame into ``out[0:3]``."""
    kinematics_pass(p, q, work, 0)
    out[0], out[1], out[2] = _ee_origin(p, work)


@njit(**ALLOCATION_FREE)
def ee_pose(p, q, pos, rot, work):  # noqa: ANN001, ANN201
    """End-effector position ``pos`` (3) and rotation ``rot`` (3 x 3) in the base frame."""
    kinematics_pass(p, q, work, 0)
    pos[0], pos[1], pos[2] = _ee_origin(p, work)
    o = int(p[N_JOINTS]) * WORK_STRIDE
    for i in range(3):
        for j in range(3):
            rot[i, j] = (work[o + 3 * i] * p[EE_ROTATION + j]
                         + work[o + 3 * i + 1] * p[EE_ROTATION + 3 + j]
                         + work[o + 3 * i + 2] * p[EE_ROTATION + 6 + j])


@njit(**ALLOCATION_FREE)
def outputs(p, q, qd, out, work):  # noqa: ANN001, ANN201, ARG001
    """End-effector position in the task plane into ``out[0:2]``: ``((x - o) . u, (x - o) . v)``."""
    kinematics_pass(p, q, work, 0)
    x, y, z = _ee_origin(p, work)
    x -= p[PLANE_ORIGIN]
    y -= p[PLANE_ORIGIN + 1]
    z -= p[PLANE_ORIGIN + 2]
    out[0] = x * p[PLANE_U] + y * p[PLANE_U + 1] + z * p[PLANE_U + 2]
    out[1] = x * p[PLANE_V] + y * p[PLANE_V + 1] + z * p[PLANE_V + 2]


@njit(**ALLOCATION_FREE)
def ee_jacobian(p, q, out, work):  # noqa: ANN001, ANN201
    """The end-effector's 6 x n Jacobian, LOCAL_WORLD_ALIGNED, into ``out``.

    Rows 0-2: velocity of the frame's origin, rows 3-5: angular velocity, both in
    base axes. Column ``k`` is ``S_k`` moved from the base origin to the frame's
    origin ``x``: ``(S_lin + S_ang x x, S_ang)``; zero beyond the frame's parent joint.
    """
    n = int(p[N_JOINTS])
    jee = int(p[EE_JOINT])
    kinematics_pass(p, q, work, 0)
    x, y, z = _ee_origin(p, work)
    for k in range(n):
        if k < jee:
            s = k * WORK_STRIDE + W_S
            tx, ty, tz = work[s + 3], work[s + 4], work[s + 5]
            cx, cy, cz = cross(tx, ty, tz, x, y, z)
            out[0, k] = work[s] + cx
            out[1, k] = work[s + 1] + cy
            out[2, k] = work[s + 2] + cz
            out[3, k] = tx
            out[4, k] = ty
            out[5, k] = tz
        else:
            for r in range(6):
                out[r, k] = 0.0
