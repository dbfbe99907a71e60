"""Compiled rigid-body dynamics of a serial chain packed from a Pinocchio model (numba).

Any serial arm of revolute and prismatic joints (the joint axis an arbitrary unit
vector of the joint frame) gets the compiled form of the thesis's robots:
:func:`terms`, :func:`gravity`, :func:`coriolis_times`, :func:`motor_inertia`,
:func:`damping`, :func:`outputs`, plus the end-effector's :func:`ee_position`,
:func:`ee_pose` and :func:`ee_jacobian`. :func:`pack` reads the model once into a
flat float array ``p``; the compiled functions read only ``p``, allocate nothing
and carve their temporaries out of the caller's scratch array ``work``
(:func:`workspace_size` floats; see :mod:`pdsmc_ros.robots.compiled`).

Algorithms
----------
Featherstone's ("Rigid Body Dynamics Algorithms", 2008) composite-rigid-body
algorithm for ``M(q)`` (ch. 6) and recursive Newton-Euler with zero
acceleration for ``C(q, qd) qd + G(q)`` (ch. 5), written -- unlike Pinocchio,
which works in the joint frames -- with every spatial quantity in base axes and
at the base origin (Featherstone section 5.3's "world coordinates"). In that
frame a joint's motion subspace is ``S = (p x z, z)`` (revolute, axis ``z``
through ``p``) or ``(z, 0)`` (prismatic), velocities add without transforms,
``Sdot = v x S`` and a composite inertia is a plain sum, so the backward passes
are sums and dot products; the one 3x3 rotation per body is its inertia's.
Spatial vectors are Pinocchio's order: linear part first, then angular.

The flat parameter array ``p``
------------------------------
Header (``HEADER_SIZE`` floats):

=========================  ====  ===================================================
offset                     size  content
=========================  ====  ===================================================
``N_JOINTS``  (0)             1  ``n``, the number of joints
``EE_JOINT``  (1)             1  the end-effector frame's parent joint, ``0..n``
                                 (0: the base)
``GRAVITY``   (2)             3  gravity acceleration in the base (``model.gravity``)
``PLANE_ORIGIN`` (5)          3  the task plane's origin, base frame
``PLANE_U``   (8)             3  the task plane's first unit axis
``PLANE_V``   (11)            3  the task plane's second unit axis
``EE_ROTATION`` (14)          9  the end-effector frame's rotation relative to its
                                 parent joint, row-major
``EE_TRANSLATION`` (23)       3  the end-effector frame's origin in its parent joint
=========================  ====  ===================================================

then one block of ``JOINT_SIZE`` floats per joint ``k = 0..n-1`` (Pinocchio's joint
``k + 1``) at ``HEADER_SIZE + k * JOINT_SIZE``, offsets within the block:

=========================  ====  ===================================================
``J_KIND``    (0)             1  ``REVOLUTE`` (0) or ``PRISMATIC`` (1)
``J_ARMATURE`` (1)            1  motor inertia ``J`` (added to ``M``'s diagonal)
``J_DAMPING`` (2)             1  motor viscous damping ``B`` (not in the bias)
``J_AXIS``    (3)             3  unit joint axis in the joint frame
``J_ROTATION`` (6)            9  rotation of the joint placement (joint frame at
                                 ``q = 0`` in its parent's), row-major
``J_TRANSLATION`` (15)        3  translation of the joint placement
``J_MASS``    (18)            1  mass of the body the joint moves
``J_LEVER``   (19)            3  its centre of mass in the joint frame
``J_INERTIA`` (22)            6  its rotational inertia about the centre of mass, in
                                 the joint frame: ``xx, yy, zz, xy, xz, yz``
=========================  ====  ===================================================

Scratch ``work``: ``WORK_STRIDE`` floats per joint (its motion subspace, first
moment and inertia about the base origin, one force), then 12 for the pose of the
end-effector's parent joint.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from .base import FloatArray
from .kernel_math import solve_spd

SERIAL_CHAIN = 2
"""Code of this compiled form (:mod:`pdsmc_ros.robots.compiled`): URDF serial arms."""

REVOLUTE = 0
"""Joint kind code of a revolute joint (``p[... + J_KIND]``)."""
PRISMATIC = 1
"""Joint kind code of a prismatic joint."""

# Header of the flat parameter array
N_JOINTS = 0
EE_JOINT = 1
GRAVITY = 2
PLANE_ORIGIN = 5
PLANE_U = 8
PLANE_V = 11
EE_ROTATION = 14
EE_TRANSLATION = 23
HEADER_SIZE = 26

# One block per joint, offsets within the block
J_KIND = 0
J_ARMATURE = 1
J_DAMPING = 2
J_AXIS = 3
J_ROTATION = 6
J_TRANSLATION = 15
J_MASS = 18
J_LEVER = 19
J_INERTIA = 22
JOINT_SIZE = 28

# Scratch per joint, offsets within its block of ``work``
_WS = 0  # motion subspace S (6): base axes, at the base origin
_WH = 6  # first moment m c (3) of the body, c its centre of mass in the base
_WIO = 9  # rotational inertia (6: xx yy zz xy xz yz) about the base origin
_WF = 15  # a spatial force (6)
WORK_STRIDE = 21
POSE_SIZE = 12
"""Floats after the per-joint scratch: rotation (row-major) and origin of the EE's parent joint."""

_TOL = 1e-9

# Pinocchio joint short names -> (kind, fixed axis or None for the unaligned joints)
_JOINTS: dict[str, tuple[int, tuple[float, float, float] | None]] = {
    "JointModelRX": (REVOLUTE, (1.0, 0.0, 0.0)),
    "JointModelRY": (REVOLUTE, (0.0, 1.0, 0.0)),
    "JointModelRZ": (REVOLUTE, (0.0, 0.0, 1.0)),
    "JointModelRevoluteUnaligned": (REVOLUTE, None),
    "JointModelPX": (PRISMATIC, (1.0, 0.0, 0.0)),
    "JointModelPY": (PRISMATIC, (0.0, 1.0, 0.0)),
    "JointModelPZ": (PRISMATIC, (0.0, 0.0, 1.0)),
    "JointModelPrismaticUnaligned": (PRISMATIC, None),
}


def workspace_size(n: int) -> int:
    """Floats of scratch ``work`` the compiled functions need for ``n`` joints: ``21 n + 12``."""
    return WORK_STRIDE * n + POSE_SIZE


def _vector3(value: ArrayLike, name: str) -> FloatArray:
    out = np.asarray(value, dtype=float)
    if out.shape != (3,) or not np.all(np.isfinite(out)):
        raise InvalidInputError(f"{name} must be 3 finite floats, got {value!r}")
    return out


def _per_joint(value: ArrayLike, n: int, name: str) -> FloatArray:
    out = np.asarray(value, dtype=float)
    if out.ndim == 0:
        out = np.full(n, float(out))
    if out.shape != (n,) or not np.all(np.isfinite(out)) or np.any(out < 0.0):
        raise InvalidInputError(f"{name} must be {n} finite non-negative floats (one per joint), got {value!r}")
    return out


def pack(
    model: Any,
    armature: ArrayLike,
    damping: ArrayLike,
    ee_frame_id: int,
    plane_origin: ArrayLike,
    plane_u: ArrayLike,
    plane_v: ArrayLike,
) -> FloatArray:
    """The flat parameter array of a serial chain (layout: the module docstring).

    Parameters
    ----------
    model : pinocchio.Model
        A serial chain (joint ``i``'s parent is joint ``i - 1``) of revolute and
        prismatic joints. Its own ``armature`` and ``damping`` are not read.
    armature : array_like
        Motor inertia ``J`` per joint (kg m^2 or kg), or one value for all.
    damping : array_like
        Motor viscous damping ``B`` per joint, or one value for all.
    ee_frame_id : int
        Index of the end-effector frame in ``model.frames``.
    plane_origin, plane_u, plane_v : array_like
        The task plane of :func:`outputs`: its origin and two orthonormal axes,
        in the base frame.

    Returns
    -------
    ndarray
        ``HEADER_SIZE + n * JOINT_SIZE`` floats.

    Raises
    ------
    InvalidInputError
        (a ``ValueError``) a tree rather than a chain, a joint other than
        revolute or prismatic, a non-unit joint axis, an unknown frame, bad
        armature, damping or plane.
    """
    n = int(model.njoints) - 1
    if n < 1:
        raise InvalidInputError("the model has no joint")
    if int(model.nq) != n or int(model.nv) != n:
        raise InvalidInputError(
            f"only 1-dof revolute and prismatic joints are supported (nq = {model.nq}, nv = {model.nv} "
            f"for {n} joints)"
        )
    parents = [int(i) for i in model.parents]
    if parents[1:] != list(range(n)):
        raise InvalidInputError(f"the model is not a serial chain (joint parents {parents[1:]})")
    if not 0 <= int(ee_frame_id) < int(model.nframes):
        raise InvalidInputError(f"no frame {ee_frame_id} (the model has {model.nframes})")
    u = _vector3(plane_u, "plane_u")
    v = _vector3(plane_v, "plane_v")
    if abs(np.linalg.norm(u) - 1.0) > _TOL or abs(np.linalg.norm(v) - 1.0) > _TOL or abs(u @ v) > _TOL:
        raise InvalidInputError(f"the plane axes must be orthonormal, got u = {u}, v = {v}")
    frame = model.frames[int(ee_frame_id)]

    p = np.zeros(HEADER_SIZE + n * JOINT_SIZE)
    p[N_JOINTS] = n
    p[EE_JOINT] = int(frame.parentJoint)
    p[GRAVITY : GRAVITY + 3] = np.asarray(model.gravity.linear, dtype=float)
    p[PLANE_ORIGIN : PLANE_ORIGIN + 3] = _vector3(plane_origin, "plane_origin")
    p[PLANE_U : PLANE_U + 3] = u
    p[PLANE_V : PLANE_V + 3] = v
    p[EE_ROTATION : EE_ROTATION + 9] = np.asarray(frame.placement.rotation, dtype=float).ravel()
    p[EE_TRANSLATION : EE_TRANSLATION + 3] = np.asarray(frame.placement.translation, dtype=float)

    motor = _per_joint(armature, n, "armature")
    friction = _per_joint(damping, n, "damping")
    for k in range(n):
        joint = model.joints[k + 1]
        name = joint.shortname()
        if name not in _JOINTS or joint.nq != 1 or joint.nv != 1 or joint.idx_v != k:
            raise InvalidInputError(
                f"joint {model.names[k + 1]!r} is a {name}: only revolute and prismatic joints are supported"
            )
        kind, fixed = _JOINTS[name]
        axis = np.asarray(joint.extract().axis if fixed is None else fixed, dtype=float)
        if abs(np.linalg.norm(axis) - 1.0) > _TOL:
            raise InvalidInputError(f"joint {model.names[k + 1]!r} has a non-unit axis {axis}")
        placement = model.jointPlacements[k + 1]
        body = model.inertias[k + 1]
        inertia = np.asarray(body.inertia, dtype=float)
        b = HEADER_SIZE + k * JOINT_SIZE
        p[b + J_KIND] = kind
        p[b + J_ARMATURE] = motor[k]
        p[b + J_DAMPING] = friction[k]
        p[b + J_AXIS : b + J_AXIS + 3] = axis
        p[b + J_ROTATION : b + J_ROTATION + 9] = np.asarray(placement.rotation, dtype=float).ravel()
        p[b + J_TRANSLATION : b + J_TRANSLATION + 3] = np.asarray(placement.translation, dtype=float)
        p[b + J_MASS] = float(body.mass)
        p[b + J_LEVER : b + J_LEVER + 3] = np.asarray(body.lever, dtype=float)
        p[b + J_INERTIA : b + J_INERTIA + 6] = [
            inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]
        ]
    return p


# --------------------------------------------------------------------------- #
# Small spatial algebra on scalars (numba inlines these; tuples cost nothing)
# --------------------------------------------------------------------------- #
@njit(cache=True)
def _cross(ax, ay, az, bx, by, bz):  # noqa: ANN001, ANN202
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(cache=True)
def _motion_cross(vx, vy, vz, wx, wy, wz, sx, sy, sz, tx, ty, tz):  # noqa: ANN001, ANN202
    """``(v, w) x (s, t)`` of two motions: ``(w x s + v x t, w x t)``."""
    ax, ay, az = _cross(wx, wy, wz, sx, sy, sz)
    bx, by, bz = _cross(vx, vy, vz, tx, ty, tz)
    cx, cy, cz = _cross(wx, wy, wz, tx, ty, tz)
    return ax + bx, ay + by, az + bz, cx, cy, cz


@njit(cache=True)
def _force_cross(vx, vy, vz, wx, wy, wz, fx, fy, fz, nx, ny, nz):  # noqa: ANN001, ANN202
    """``(v, w) x* (f, n)``, motion on force: ``(w x f, w x n + v x f)``."""
    ax, ay, az = _cross(wx, wy, wz, fx, fy, fz)
    bx, by, bz = _cross(wx, wy, wz, nx, ny, nz)
    cx, cy, cz = _cross(vx, vy, vz, fx, fy, fz)
    return ax, ay, az, bx + cx, by + cy, bz + cz


@njit(cache=True)
def _inertia_times(m, hx, hy, hz, ixx, iyy, izz, ixy, ixz, iyz, vx, vy, vz, wx, wy, wz):  # noqa: ANN001, ANN202
    """Spatial inertia (mass ``m``, first moment ``h``, inertia ``I`` about the origin) times ``(v, w)``.

    ``f = m v - h x w`` and ``n = I w + h x v`` (momentum of a body about the origin).
    """
    ax, ay, az = _cross(hx, hy, hz, wx, wy, wz)
    bx, by, bz = _cross(hx, hy, hz, vx, vy, vz)
    return (
        m * vx - ax,
        m * vy - ay,
        m * vz - az,
        ixx * wx + ixy * wy + ixz * wz + bx,
        ixy * wx + iyy * wy + iyz * wz + by,
        ixz * wx + iyz * wy + izz * wz + bz,
    )


@njit(cache=True)
def _body_times(p, work, k, vx, vy, vz, wx, wy, wz):  # noqa: ANN001, ANN202
    """Body ``k``'s spatial inertia (base frame, from :func:`_forward`) times ``(v, w)``."""
    o = k * WORK_STRIDE
    h = o + _WH
    i = o + _WIO
    return _inertia_times(
        p[HEADER_SIZE + k * JOINT_SIZE + J_MASS], work[h], work[h + 1], work[h + 2],
        work[i], work[i + 1], work[i + 2], work[i + 3], work[i + 4], work[i + 5],
        vx, vy, vz, wx, wy, wz,
    )


@njit(cache=True)
def _dot_s(work, k, fx, fy, fz, nx, ny, nz):  # noqa: ANN001, ANN202
    """``S_k . (f, n)``: joint ``k``'s share of a spatial force (its torque or force)."""
    s = k * WORK_STRIDE + _WS
    return (work[s] * fx + work[s + 1] * fy + work[s + 2] * fz
            + work[s + 3] * nx + work[s + 4] * ny + work[s + 5] * nz)


# --------------------------------------------------------------------------- #
# Passes
# --------------------------------------------------------------------------- #
@njit(cache=True)
def _forward(p, q, work, level):  # noqa: ANN001, ANN202
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
            s = k * WORK_STRIDE + _WS
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
                lx, ly, lz = _cross(px, py, pz, zx, zy, zz)
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
                h = k * WORK_STRIDE + _WH
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
                    o = k * WORK_STRIDE + _WIO
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


@njit(cache=True)
def _bias_forces(p, x, gscale, work):  # noqa: ANN001, ANN202
    """RNEA's forward pass with ``qdd = 0``: each body's force ``I a + v x* I v`` into ``work``.

    The base accelerates at ``-gscale * g`` (gravity as a fictitious base
    acceleration, as Pinocchio). Needs :func:`_forward` at level 2.
    """
    n = int(p[N_JOINTS])
    vx, vy, vz, wx, wy, wz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    ax = -gscale * p[GRAVITY]
    ay = -gscale * p[GRAVITY + 1]
    az = -gscale * p[GRAVITY + 2]
    bx, by, bz = 0.0, 0.0, 0.0
    for k in range(n):
        s = k * WORK_STRIDE + _WS
        xk = x[k]
        sx, sy, sz = work[s] * xk, work[s + 1] * xk, work[s + 2] * xk
        tx, ty, tz = work[s + 3] * xk, work[s + 4] * xk, work[s + 5] * xk
        # a_k = a_{k-1} + v_k x S_k x_k = a_{k-1} + v_{k-1} x S_k x_k (Sdot = v x S)
        c0, c1, c2, c3, c4, c5 = _motion_cross(vx, vy, vz, wx, wy, wz, sx, sy, sz, tx, ty, tz)
        ax, ay, az, bx, by, bz = ax + c0, ay + c1, az + c2, bx + c3, by + c4, bz + c5
        vx, vy, vz, wx, wy, wz = vx + sx, vy + sy, vz + sz, wx + tx, wy + ty, wz + tz
        f0, f1, f2, f3, f4, f5 = _body_times(p, work, k, ax, ay, az, bx, by, bz)
        m0, m1, m2, m3, m4, m5 = _body_times(p, work, k, vx, vy, vz, wx, wy, wz)
        g0, g1, g2, g3, g4, g5 = _force_cross(vx, vy, vz, wx, wy, wz, m0, m1, m2, m3, m4, m5)
        f = k * WORK_STRIDE + _WF
        work[f], work[f + 1], work[f + 2] = f0 + g0, f1 + g1, f2 + g2
        work[f + 3], work[f + 4], work[f + 5] = f3 + g3, f4 + g4, f5 + g5


@njit(cache=True)
def _project_forces(p, out, work):  # noqa: ANN001, ANN202
    """RNEA's backward pass: ``out_k = S_k . (sum of the forces of bodies k..n-1)``."""
    n = int(p[N_JOINTS])
    fx, fy, fz, nx, ny, nz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for k in range(n - 1, -1, -1):
        f = k * WORK_STRIDE + _WF
        fx += work[f]
        fy += work[f + 1]
        fz += work[f + 2]
        nx += work[f + 3]
        ny += work[f + 4]
        nz += work[f + 5]
        out[k] = _dot_s(work, k, fx, fy, fz, nx, ny, nz)


# --------------------------------------------------------------------------- #
# The compiled form
# --------------------------------------------------------------------------- #
@njit(cache=True)
def terms(p, q, qd, mass, bias, work):  # noqa: ANN001, ANN201
    """``mass = M(q) + diag(J)`` (both triangles) and ``bias = C(q, qd) qd + G(q)``.

    CRBA and RNEA (``qdd = 0``, gravity included) share one kinematics pass and
    one backward pass: in base coordinates the composite inertia of bodies
    ``k..n-1`` is the plain sum of theirs, and ``M_ik = S_i . (I^c_k S_k)`` for
    ``i <= k``.
    """
    n = int(p[N_JOINTS])
    _forward(p, q, work, 2)
    _bias_forces(p, qd, 1.0, work)
    cm = 0.0
    hx, hy, hz = 0.0, 0.0, 0.0
    ixx, iyy, izz, ixy, ixz, iyz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    fx, fy, fz, nx, ny, nz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for k in range(n - 1, -1, -1):
        o = k * WORK_STRIDE
        b = HEADER_SIZE + k * JOINT_SIZE
        cm += p[b + J_MASS]
        hx += work[o + _WH]
        hy += work[o + _WH + 1]
        hz += work[o + _WH + 2]
        ixx += work[o + _WIO]
        iyy += work[o + _WIO + 1]
        izz += work[o + _WIO + 2]
        ixy += work[o + _WIO + 3]
        ixz += work[o + _WIO + 4]
        iyz += work[o + _WIO + 5]
        fx += work[o + _WF]
        fy += work[o + _WF + 1]
        fz += work[o + _WF + 2]
        nx += work[o + _WF + 3]
        ny += work[o + _WF + 4]
        nz += work[o + _WF + 5]
        bias[k] = _dot_s(work, k, fx, fy, fz, nx, ny, nz)
        s = o + _WS
        g0, g1, g2, g3, g4, g5 = _inertia_times(
            cm, hx, hy, hz, ixx, iyy, izz, ixy, ixz, iyz,
            work[s], work[s + 1], work[s + 2], work[s + 3], work[s + 4], work[s + 5],
        )
        for i in range(k):
            mik = _dot_s(work, i, g0, g1, g2, g3, g4, g5)
            mass[i, k] = mik
            mass[k, i] = mik
        mass[k, k] = _dot_s(work, k, g0, g1, g2, g3, g4, g5) + p[b + J_ARMATURE]


@njit(cache=True)
def gravity(p, q, out, work):  # noqa: ANN001, ANN201
    """``G(q)``: the composite mass ``M_k`` and first moment ``H_k`` of bodies ``k..n-1`` hold
    ``(-M_k g, g x H_k)``, and ``G_k = S_k`` . that."""
    n = int(p[N_JOINTS])
    _forward(p, q, work, 1)
    gx, gy, gz = p[GRAVITY], p[GRAVITY + 1], p[GRAVITY + 2]
    cm = 0.0
    hx, hy, hz = 0.0, 0.0, 0.0
    for k in range(n - 1, -1, -1):
        o = k * WORK_STRIDE + _WH
        cm += p[HEADER_SIZE + k * JOINT_SIZE + J_MASS]
        hx += work[o]
        hy += work[o + 1]
        hz += work[o + 2]
        nx, ny, nz = _cross(gx, gy, gz, hx, hy, hz)
        out[k] = _dot_s(work, k, -cm * gx, -cm * gy, -cm * gz, nx, ny, nz)


@njit(cache=True)
def coriolis_times(p, q, qd, v, out, work):  # noqa: ANN001, ANN201
    """``C(q, qd) v`` with the Christoffel-symbol ``C``.

    ``c(x) = C(q, x) x`` (RNEA without gravity) is a quadratic form in ``x`` and the
    Christoffel symbols are its symmetric bilinear form, so ``C(q, qd) v = B(qd, v)``
    with ``B`` the polarisation of ``c``. One RNEA-like pass evaluates ``B``
    directly, symmetrising each quadratic term: exact, and without the
    cancellation of ``(c(qd + v) - c(qd - v)) / 4``.
    """
    n = int(p[N_JOINTS])
    _forward(p, q, work, 2)
    vx, vy, vz, wx, wy, wz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0  # velocity of x = qd
    ux, uy, uz, yx, yy, yz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0  # velocity of y = v
    ax, ay, az, bx, by, bz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0  # the bilinear acceleration
    for k in range(n):
        s = k * WORK_STRIDE + _WS
        xk = qd[k]
        yk = v[k]
        s0, s1, s2, s3, s4, s5 = work[s], work[s + 1], work[s + 2], work[s + 3], work[s + 4], work[s + 5]
        # a += (v_x x S y_k + v_y x S x_k) / 2 with the velocities of bodies 0..k-1
        c0, c1, c2, c3, c4, c5 = _motion_cross(vx, vy, vz, wx, wy, wz, s0 * yk, s1 * yk, s2 * yk,
                                               s3 * yk, s4 * yk, s5 * yk)
        d0, d1, d2, d3, d4, d5 = _motion_cross(ux, uy, uz, yx, yy, yz, s0 * xk, s1 * xk, s2 * xk,
                                               s3 * xk, s4 * xk, s5 * xk)
        ax += 0.5 * (c0 + d0)
        ay += 0.5 * (c1 + d1)
        az += 0.5 * (c2 + d2)
        bx += 0.5 * (c3 + d3)
        by += 0.5 * (c4 + d4)
        bz += 0.5 * (c5 + d5)
        vx, vy, vz, wx, wy, wz = vx + s0 * xk, vy + s1 * xk, vz + s2 * xk, wx + s3 * xk, wy + s4 * xk, wz + s5 * xk
        ux, uy, uz, yx, yy, yz = ux + s0 * yk, uy + s1 * yk, uz + s2 * yk, yx + s3 * yk, yy + s4 * yk, yz + s5 * yk
        # f = I a + (v_x x* I v_y + v_y x* I v_x) / 2
        f0, f1, f2, f3, f4, f5 = _body_times(p, work, k, ax, ay, az, bx, by, bz)
        m0, m1, m2, m3, m4, m5 = _body_times(p, work, k, ux, uy, uz, yx, yy, yz)
        g0, g1, g2, g3, g4, g5 = _force_cross(vx, vy, vz, wx, wy, wz, m0, m1, m2, m3, m4, m5)
        m0, m1, m2, m3, m4, m5 = _body_times(p, work, k, vx, vy, vz, wx, wy, wz)
        h0, h1, h2, h3, h4, h5 = _force_cross(ux, uy, uz, yx, yy, yz, m0, m1, m2, m3, m4, m5)
        f = k * WORK_STRIDE + _WF
        work[f] = f0 + 0.5 * (g0 + h0)
        work[f + 1] = f1 + 0.5 * (g1 + h1)
        work[f + 2] = f2 + 0.5 * (g2 + h2)
        work[f + 3] = f3 + 0.5 * (g3 + h3)
        work[f + 4] = f4 + 0.5 * (g4 + h4)
        work[f + 5] = f5 + 0.5 * (g5 + h5)
    _project_forces(p, out, work)


@njit(cache=True)
def accelerations(p, q, qd, tau, out, work):  # noqa: ANN001, ANN201
    """Eq. (4.1): ``qdd = Mbar^{-1} (tau - C qd - B qd - G)`` into ``out`` (:func:`terms`, then a
    Cholesky solve)."""
    n = q.shape[0]
    rhs = work[0:n]
    mass = work[n : n + n * n].reshape((n, n))
    rest = work[n + n * n :]
    terms(p, q, qd, mass, rhs, rest)
    for i in range(n):
        rhs[i] = tau[i] - rhs[i] - damping(p, i) * qd[i]
    solve_spd(mass, rhs, out, n)


@njit(cache=True)
def motor_inertia(p, i):  # noqa: ANN001, ANN201
    """Motor inertia ``J_i``."""
    return p[HEADER_SIZE + i * JOINT_SIZE + J_ARMATURE]


@njit(cache=True)
def damping(p, i):  # noqa: ANN001, ANN201
    """Motor viscous damping ``B_i``."""
    return p[HEADER_SIZE + i * JOINT_SIZE + J_DAMPING]


@njit(cache=True)
def _ee_origin(p, work):  # noqa: ANN001, ANN202
    """The end-effector's origin in the base from its parent joint's pose (after :func:`_forward`)."""
    o = int(p[N_JOINTS]) * WORK_STRIDE
    tx, ty, tz = p[EE_TRANSLATION], p[EE_TRANSLATION + 1], p[EE_TRANSLATION + 2]
    return (work[o + 9] + work[o] * tx + work[o + 1] * ty + work[o + 2] * tz,
            work[o + 10] + work[o + 3] * tx + work[o + 4] * ty + work[o + 5] * tz,
            work[o + 11] + work[o + 6] * tx + work[o + 7] * ty + work[o + 8] * tz)


@njit(cache=True)
def ee_position(p, q, out, work):  # noqa: ANN001, ANN201
    """End-effector position in the base frame into ``out[0:3]``."""
    _forward(p, q, work, 0)
    out[0], out[1], out[2] = _ee_origin(p, work)


@njit(cache=True)
def ee_pose(p, q, pos, rot, work):  # noqa: ANN001, ANN201
    """End-effector position ``pos`` (3) and rotation ``rot`` (3 x 3) in the base frame."""
    _forward(p, q, work, 0)
    pos[0], pos[1], pos[2] = _ee_origin(p, work)
    o = int(p[N_JOINTS]) * WORK_STRIDE
    for i in range(3):
        for j in range(3):
            rot[i, j] = (work[o + 3 * i] * p[EE_ROTATION + j]
                         + work[o + 3 * i + 1] * p[EE_ROTATION + 3 + j]
                         + work[o + 3 * i + 2] * p[EE_ROTATION + 6 + j])


@njit(cache=True)
def outputs(p, q, qd, out, work):  # noqa: ANN001, ANN201, ARG001
    """End-effector position in the task plane into ``out[0:2]``: ``((x - o) . u, (x - o) . v)``."""
    _forward(p, q, work, 0)
    x, y, z = _ee_origin(p, work)
    x -= p[PLANE_ORIGIN]
    y -= p[PLANE_ORIGIN + 1]
    z -= p[PLANE_ORIGIN + 2]
    out[0] = x * p[PLANE_U] + y * p[PLANE_U + 1] + z * p[PLANE_U + 2]
    out[1] = x * p[PLANE_V] + y * p[PLANE_V + 1] + z * p[PLANE_V + 2]


@njit(cache=True)
def ee_jacobian(p, q, out, work):  # noqa: ANN001, ANN201
    """The end-effector's 6 x n Jacobian, LOCAL_WORLD_ALIGNED, into ``out``.

    Rows 0-2: velocity of the frame's origin, rows 3-5: angular velocity, both in
    base axes. Column ``k`` is ``S_k`` moved from the base origin to the frame's
    origin ``x``: ``(S_lin + S_ang x x, S_ang)``; zero beyond the frame's parent joint.
    """
    n = int(p[N_JOINTS])
    jee = int(p[EE_JOINT])
    _forward(p, q, work, 0)
    x, y, z = _ee_origin(p, work)
    for k in range(n):
        if k < jee:
            s = k * WORK_STRIDE + _WS
            tx, ty, tz = work[s + 3], work[s + 4], work[s + 5]
            cx, cy, cz = _cross(tx, ty, tz, x, y, z)
            out[0, k] = work[s] + cx
            out[1, k] = work[s + 1] + cy
            out[2, k] = work[s + 2] + cz
            out[3, k] = tx
            out[4, k] = ty
            out[5, k] = tz
        else:
            for r in range(6):
                out[r, k] = 0.0
