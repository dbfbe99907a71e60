"""The packed serial chain: its flat parameter array, read once from a Pinocchio model, and
the small spatial algebra its kernels share (numba).

Any serial arm of revolute and prismatic joints (the joint axis an arbitrary unit
vector of the joint frame) gets the compiled form of the thesis's robots:
:func:`pack` reads the model once into a flat float array ``p``; the kernels --
kinematics in :mod:`.spatial_kernels`, dynamics in :mod:`.spatial_dynamics` -- read
only ``p``, allocate nothing and carve their temporaries out of the caller's scratch
array ``work`` (:func:`workspace_size` floats; see :mod:`pdsmc_ros.robots.compiled`).
Every spatial quantity is in base axes and at the base origin
(:mod:`.spatial_dynamics`); spatial vectors are Pinocchio's order: linear part first,
then angular.

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

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from ..errors import InvalidInputError
from ..kernels.options import ALLOCATION_FREE
from .base import FloatArray

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
W_S = 0  # motion subspace S (6): base axes, at the base origin
W_H = 6  # first moment m c (3) of the body, c its centre of mass in the base
W_IO = 9  # rotational inertia (6: xx yy zz xy xz yz) about the base origin
W_F = 15  # a spatial force (6)
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
@njit(**ALLOCATION_FREE)
def cross(ax, ay, az, bx, by, bz):  # noqa: ANN001, ANN202
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(**ALLOCATION_FREE)
def motion_cross(vx, vy, vz, wx, wy, wz, sx, sy, sz, tx, ty, tz):  # noqa: ANN001, ANN202
    """``(v, w) x (s, t)`` of two motions: ``(w x s + v x t, w x t)``."""
    ax, ay, az = cross(wx, wy, wz, sx, sy, sz)
    bx, by, bz = cross(vx, vy, vz, tx, ty, tz)
    cx, cy, cz = cross(wx, wy, wz, tx, ty, tz)
    return ax + bx, ay + by, az + bz, cx, cy, cz


@njit(**ALLOCATION_FREE)
def force_cross(vx, vy, vz, wx, wy, wz, fx, fy, fz, nx, ny, nz):  # noqa: ANN001, ANN202
    """``(v, w) x* (f, n)``, motion on force: ``(w x f, w x n + v x f)``."""
    ax, ay, az = cross(wx, wy, wz, fx, fy, fz)
    bx, by, bz = cross(wx, wy, wz, nx, ny, nz)
    cx, cy, cz = cross(vx, vy, vz, fx, fy, fz)
    return ax, ay, az, bx + cx, by + cy, bz + cz


@njit(**ALLOCATION_FREE)
def inertia_times(m, hx, hy, hz, ixx, iyy, izz, ixy, ixz, iyz, vx, vy, vz, wx, wy, wz):  # noqa: ANN001, ANN202
    """Spatial inertia (mass ``m``, first moment ``h``, inertia ``I`` about the origin) times ``(v, w)``.

    ``f = m v - h x w`` and ``n = I w + h x v`` (momentum of a body about the origin).
    """
    ax, ay, az = cross(hx, hy, hz, wx, wy, wz)
    bx, by, bz = cross(hx, hy, hz, vx, vy, vz)
    return (
        m * vx - ax,
        m * vy - ay,
        m * vz - az,
        ixx * wx + ixy * wy + ixz * wz + bx,
        ixy * wx + iyy * wy + iyz * wz + by,
        ixz * wx + iyz * wy + izz * wz + bz,
    )


@njit(**ALLOCATION_FREE)
def body_times(p, work, k, vx, vy, vz, wx, wy, wz):  # noqa: ANN001, ANN202
    """Body ``k``'s spatial inertia (base frame, from :func:`kinematics_pass`) times ``(v, w)``."""
    o = k * WORK_STRIDE
    h = o + W_H
    i = o + W_IO
    return inertia_times(
        p[HEADER_SIZE + k * JOINT_SIZE + J_MASS], work[h], work[h + 1], work[h + 2],
        work[i], work[i + 1], work[i + 2], work[i + 3], work[i + 4], work[i + 5],
        vx, vy, vz, wx, wy, wz,
    )


@njit(**ALLOCATION_FREE)
def dot_s(work, k, fx, fy, fz, nx, ny, nz):  # noqa: ANN001, ANN202
    """``S_k . (f, n)``: joint ``k``'s share of a spatial force (its torque or force)."""
    s = k * WORK_STRIDE + W_S
    return (work[s] * fx + work[s + 1] * fy + work[s + 2] * fz
            + work[s + 3] * nx + work[s + 4] * ny + work[s + 5] * nz)
