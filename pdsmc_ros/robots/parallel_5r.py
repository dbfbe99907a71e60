"""The planar five-bar (parallel 5R) of Section 4.1.2: the numpy model.

Fig. 4.2, Table 4.2 (``config/robots.yaml``), driven at its two base joints,
with the reduced model of Ghorbel (1995), Eqs. (4.2) and Appendix Eqs.
(47)-(70). The dynamics are written once, in its compiled form
(:mod:`pdsmc_ros.robots.parallel_5r_kernels`), which the methods here call over batches; the
position analysis (forward and inverse kinematics, the loop-closure Jacobian) is here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InvalidInputError, SingularConfigurationError, UnreachableError
from .base import FloatArray, Manipulator, RobotParams, as_vector
from .chain import PlanarChain
from .parallel_5r_kernels import PARALLEL_5R, batch_coriolis_matrix, batch_terms
from .registry import robot_params
from .urdf import five_bar_urdf

_SINGULAR_TOL = 1e-9
_WORK = 64  # floats of the compiled form's scratch (its largest use: the geometry's 24, and the batch's 4 at the end)


@dataclass
class FiveBarState:
    """Open-tree coordinates of the five-bar: ``q' = (q1, q2, q3, q4)``.

    ``rho`` maps actuated rates to open-tree rates (Appendix Eq. 56), stored as
    the two chains' rows: ``rho_left`` rows (q1, q3), ``rho_right`` rows (q2, q4).
    """

    q_left: FloatArray
    q_right: FloatArray
    rho_left: FloatArray
    rho_right: FloatArray
    constraint_passive: FloatArray = field(repr=False)


class Parallel5R(Manipulator):
    """Planar five-bar (parallel 5R) manipulator of Section 4.1.2 (Fig. 4.2, Table 4.2).

    Actuated joints ``q1`` at ``O1 = (0, 0)`` and ``q2`` at ``O2 = (L5, 0)``;
    the left chain is links 1 and 3 (relative angle ``q3``), the right chain
    links 2 and 4 (relative angle ``q4``); the end-effector is the common
    distal joint. Dynamics: the reduced model of Eqs. (4.2) and (56)-(70),
    ``M = rho^T M' rho + J``, ``C = rho^T C' rho + rho^T M' rhodot``,
    ``G = rho^T G'``.

    Parameters
    ----------
    payload : float, optional
        Point mass at the end-effector (kg), carried by the left chain's tip.
    params : RobotParams, optional
        Table 4.2 by default.
    assembly_mode : {+1, -1}, optional
        Side of the line ``A1 A2`` (the two elbows) on which the end-effector
        lies; ``+1`` (left of ``A1 -> A2``) is the thesis configuration. Kept
        constant along a motion so the passive joints stay continuous.
    left_elbow, right_elbow : {+1, -1}, optional
        Sign of ``q3`` and ``q4`` chosen by :meth:`inverse_kinematics`; the
        defaults (-1, +1) reproduce Table 4.6 (docs/THESIS_NOTES.md section 3).
    """

    name = "parallel_5r"
    n = 2
    task_dim = 2
    joint_names = ("joint1", "joint2")
    passive_joint_names = ("joint3", "joint4")
    payload_link = 2  # the left distal link carries the end-effector point
    kernel = PARALLEL_5R

    def __init__(
        self,
        payload: float = 0.0,
        *,
        params: RobotParams | None = None,
        assembly_mode: int = 1,
        left_elbow: int = -1,
        right_elbow: int = 1,
    ) -> None:
        params = params or robot_params(self.name)
        if len(params.links) != 4:
            raise InvalidInputError(f"parallel_5r needs 4 links, got {len(params.links)}")
        for name, value in (
            ("assembly_mode", assembly_mode),
            ("left_elbow", left_elbow),
            ("right_elbow", right_elbow),
        ):
            if value not in (1, -1):
                raise InvalidInputError(f"{name} must be +1 or -1, got {value!r}")
        if params.base_length <= 0.0:
            raise InvalidInputError(f"base_length must be > 0, got {params.base_length!r}")
        super().__init__(payload, params=params)
        self.assembly_mode = assembly_mode
        self.left_elbow = left_elbow
        self.right_elbow = right_elbow
        l1, l2, l3, l4 = params.links
        self.left = PlanarChain((l1, l3), tip_mass=payload, gravity=params.gravity)
        self.right = PlanarChain(
            (l2, l4), base=(params.base_length, 0.0), gravity=params.gravity
        )
        self.L1, self.L2, self.L3, self.L4 = (link.length for link in params.links)
        self.L5 = params.base_length

    def pack(self) -> FloatArray:
        """Flat parameters of the compiled form (layout: :mod:`.parallel_5r_kernels`)."""
        parts = [
            *_chain_parts(self.left),
            *_chain_parts(self.right),
            [self.L5],
            self.J,
            self.B,
            [self.left.gravity, float(self.assembly_mode)],
        ]
        return np.concatenate([np.asarray(x, dtype=float).ravel() for x in parts])

    def description(self, payload: float | None = None) -> str:
        """The mechanism's URDF, its open tree (:func:`pdsmc_ros.robots.urdf.five_bar_urdf`)."""
        return five_bar_urdf(self.name, self.params, self.payload if payload is None else payload)

    def with_payload(self, payload: float) -> Parallel5R:
        """The same mechanism carrying ``payload`` kg at the end-effector."""
        return Parallel5R(
            payload,
            params=self.params,
            assembly_mode=self.assembly_mode,
            left_elbow=self.left_elbow,
            right_elbow=self.right_elbow,
        )

    # -- position analysis --------------------------------------------------- #
    def _elbows(self, q: FloatArray) -> tuple[FloatArray, FloatArray]:
        a1 = np.stack([self.L1 * np.cos(q[..., 0]), self.L1 * np.sin(q[..., 0])], axis=-1)
        a2 = np.stack(
            [self.L5 + self.L2 * np.cos(q[..., 1]), self.L2 * np.sin(q[..., 1])], axis=-1
        )
        return a1, a2

    def _end_effector(self, q: FloatArray, *, check: bool = False) -> FloatArray:
        """Forward position (Appendix Eqs. 26-34) as a circle intersection.

        Written per coordinate (the elbows ``a1``, ``a2`` of :meth:`_elbows`, ``u = a2 - a1``, its
        unit vector and normal): the same floats as in vectors of two, without the stacking and
        the reductions over an axis of two, which cost a Monte Carlo run's samples more than the
        arithmetic.
        """
        a1x = self.L1 * np.cos(q[..., 0])
        a1y = self.L1 * np.sin(q[..., 0])
        ux = self.L5 + self.L2 * np.cos(q[..., 1]) - a1x
        uy = self.L2 * np.sin(q[..., 1]) - a1y
        d2 = ux * ux + uy * uy
        d = np.sqrt(d2)
        along = (d2 + self.L3**2 - self.L4**2) / (2.0 * d)
        h2 = self.L3**2 - along * along
        if check and np.any(h2 <= _SINGULAR_TOL * self.L3**2):
            raise SingularConfigurationError(
                f"q = {np.array2string(np.asarray(q), precision=6)}: the five-bar cannot "
                "assemble there or is at a forward singularity (links 3 and 4 aligned)"
            )
        normal_scale = self.assembly_mode * np.sqrt(np.maximum(h2, 0.0))
        unit_x = ux / d
        unit_y = uy / d
        # a1 + along unit + (mode h) normal, with the normal (-unit_y, unit_x)
        return np.stack([a1x + along * unit_x + normal_scale * -unit_y,
                         a1y + along * unit_y + normal_scale * unit_x], axis=-1)

    def open_tree(self, q: FloatArray, *, check: bool = False) -> tuple[FloatArray, FloatArray]:
        """Joint angles of both chains: ``(q1, q3)`` and ``(q2, q4)``, q3/q4 in (-pi, pi]."""
        a1, a2 = self._elbows(q)
        p = self._end_effector(q, check=check)
        th3 = np.arctan2(p[..., 1] - a1[..., 1], p[..., 0] - a1[..., 0])
        th4 = np.arctan2(p[..., 1] - a2[..., 1], p[..., 0] - a2[..., 0])
        q3 = _wrap(th3 - q[..., 0])
        q4 = _wrap(th4 - q[..., 1])
        return (
            np.stack([q[..., 0], q3], axis=-1),
            np.stack([q[..., 1], q4], axis=-1),
        )

    def state(self, q: FloatArray, *, check: bool = False) -> FiveBarState:
        """Open-tree angles and ``rho`` (Eq. 56) via the loop-closure Jacobian."""
        q_left, q_right = self.open_tree(q, check=check)
        j_left = self.left.tip_jacobian(q_left)  # d tip / d (q1, q3)
        j_right = self.right.tip_jacobian(q_right)  # d tip / d (q2, q4)
        # Constraint phi = tip_left - tip_right = 0 (Eqs. 47-55):
        # [j_left[:,0], -j_right[:,0]] qd_act + [j_left[:,1], -j_right[:,1]] qd_pas = 0
        a_act = np.stack([j_left[..., :, 0], -j_right[..., :, 0]], axis=-1)
        a_pas = np.stack([j_left[..., :, 1], -j_right[..., :, 1]], axis=-1)
        if check:
            det = np.linalg.det(a_pas)
            if np.any(np.abs(det) < _SINGULAR_TOL):
                raise SingularConfigurationError(
                    f"q = {np.array2string(np.asarray(q), precision=6)}: loop-closure Jacobian "
                    "is singular (forward singularity of the five-bar)"
                )
        r = -np.linalg.solve(a_pas, a_act)  # d(q3, q4)/d(q1, q2)
        eye_rows = np.broadcast_to(np.eye(2), r.shape)
        rho_left = np.stack([eye_rows[..., 0, :], r[..., 0, :]], axis=-2)
        rho_right = np.stack([eye_rows[..., 1, :], r[..., 1, :]], axis=-2)
        return FiveBarState(q_left, q_right, rho_left, rho_right, a_pas)

    def passive_joints(self, q: FloatArray, qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(q3, q4)`` and their rates for actuated ``q``, ``qd``."""
        st = self.state(q)
        qd_left = np.einsum("...ij,...j->...i", st.rho_left, qd)
        qd_right = np.einsum("...ij,...j->...i", st.rho_right, qd)
        return (
            np.stack([st.q_left[..., 1], st.q_right[..., 1]], axis=-1),
            np.stack([qd_left[..., 1], qd_right[..., 1]], axis=-1),
        )

    def _fk(self, q: FloatArray) -> FloatArray:
        return self._end_effector(q, check=True)

    def position(self, q: FloatArray) -> FloatArray:
        return self._end_effector(q)

    def _ik(self, p: FloatArray) -> FloatArray:
        """Two 2R inverse problems (Appendix Eqs. 35-42) with the thesis branches."""
        q1, _ = _two_link_ik(p, np.zeros(2), self.L1, self.L3, self.left_elbow, "left (O1)", p)
        q2, _ = _two_link_ik(
            p, np.array([self.L5, 0.0]), self.L2, self.L4, self.right_elbow, "right (O2)", p
        )
        return np.stack([_wrap(q1), _wrap(q2)], axis=-1)

    def reachable(self, p: ArrayLike) -> NDArray[np.bool_]:
        p = as_vector(p, 2, "p")
        ok = np.ones(p.shape[:-1], dtype=bool)
        for base, a, b in (((0.0, 0.0), self.L1, self.L3), ((self.L5, 0.0), self.L2, self.L4)):
            d2 = (p[..., 0] - base[0]) ** 2 + (p[..., 1] - base[1]) ** 2
            c = (d2 - a * a - b * b) / (2.0 * a * b)
            ok &= np.abs(c) < 1.0 - 1e-9
        return ok

    def joint_rates(
        self, q: FloatArray, pd: FloatArray, pdd: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        rates = []
        accels = []
        for chain, angles in zip((self.left, self.right), self.open_tree(q), strict=True):
            jac = chain.tip_jacobian(angles)
            rate = np.linalg.solve(jac, pd[..., None])[..., 0]
            rhs = pdd - np.einsum("...ij,...j->...i", chain.tip_jacobian_dot(angles, rate), rate)
            rates.append(rate[..., 0])
            accels.append(np.linalg.solve(jac, rhs[..., None])[..., 0][..., 0])
        return np.stack(rates, axis=-1), np.stack(accels, axis=-1)

    def _jacobian(self, q: FloatArray) -> FloatArray:
        st = self.state(q, check=True)
        return np.einsum("...ij,...jk->...ik", self.left.tip_jacobian(st.q_left), st.rho_left)

    # -- dynamics: the compiled form's, over any leading batch axes ----------- #
    def _batch(self, q: FloatArray, qd: FloatArray | None = None) -> tuple[FloatArray, FloatArray, tuple[int, ...]]:
        shape = q.shape[:-1]
        flat_q = np.ascontiguousarray(q, dtype=float).reshape(-1, 2)
        flat_qd = np.zeros_like(flat_q) if qd is None else np.ascontiguousarray(np.broadcast_to(qd, q.shape),
                                                                                 dtype=float).reshape(-1, 2)
        return flat_q, flat_qd, shape

    def _bias(self, q: FloatArray, qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``Mbar`` and ``C qd + G`` (Eqs. 56-70) from the compiled form (:func:`.parallel_5r_kernels.terms`)."""
        flat_q, flat_qd, shape = self._batch(q, qd)
        mass = np.empty((len(flat_q), 2, 2))
        bias = np.empty((len(flat_q), 2))
        batch_terms(self.pack(), flat_q, flat_qd, mass, bias, np.empty(_WORK))
        return mass.reshape(shape + (2, 2)), bias.reshape(shape + (2,))

    def _mass_matrix(self, q: FloatArray) -> FloatArray:
        return self._bias(q, np.zeros_like(q))[0]

    def _gravity(self, q: FloatArray) -> FloatArray:
        return self._bias(q, np.zeros_like(q))[1]

    def _coriolis_matrix(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        """``C = rho^T C' rho + rho^T M' rhodot`` (Eq. 57) from the compiled form, column by column."""
        flat_q, flat_qd, shape = self._batch(q, qd)
        out = np.empty((len(flat_q), 2, 2))
        batch_coriolis_matrix(self.pack(), flat_q, flat_qd, out, np.empty(_WORK))
        return out.reshape(shape + (2, 2))

    def _potential(self, q: FloatArray) -> FloatArray:
        q_left, q_right = self.open_tree(q)
        return self.left.potential_energy(q_left) + self.right.potential_energy(q_right)



def _congruence(rho: FloatArray, m: FloatArray) -> FloatArray:
    """``rho^T m rho``."""
    return np.einsum("...ji,...jk,...kl->...il", rho, m, rho)


def _wrap(angle: FloatArray) -> FloatArray:
    """Wrap to (-pi, pi]."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


def _two_link_ik(
    p: FloatArray,
    base: FloatArray,
    a: float,
    b: float,
    elbow: int,
    label: str,
    original: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Base and elbow angles of a 2R chain (lengths ``a``, ``b``) reaching ``p``."""
    dx = p[..., 0] - base[0]
    dy = p[..., 1] - base[1]
    d2 = dx * dx + dy * dy
    c = (d2 - a * a - b * b) / (2.0 * a * b)
    bad = np.abs(c) > 1.0 - 1e-12
    if np.any(bad):
        idx = np.argwhere(np.atleast_1d(bad))[0][0]
        point = np.atleast_2d(original)[idx]
        dist = np.sqrt(np.atleast_1d(d2)[idx])
        raise UnreachableError(
            f"p = {np.array2string(point, precision=6)} is outside the parallel_5r workspace: "
            f"the {label} chain reaches {abs(a - b):.4g}..{a + b:.4g} m, the point is "
            f"{dist:.4g} m away (or at a chain's boundary singularity)"
        )
    elbow_angle = elbow * np.arccos(c)
    base_angle = np.arctan2(dy, dx) - np.arctan2(
        b * np.sin(elbow_angle), a + b * np.cos(elbow_angle)
    )
    return base_angle, elbow_angle


def _chain_parts(chain: PlanarChain) -> list[FloatArray]:
    return [chain.W.ravel(), chain.w, chain.inertias, chain.lengths]
