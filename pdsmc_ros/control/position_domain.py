"""PD and PD-SMC in the master's position domain (the thesis's Section 5.3 future work), written once, compiled.

Position domain control (PDC; Ouyang, Pano & Dam, "PID position domain control for contour
tracking", Int. J. Systems Science 46(1), 2015; Ouyang, Pano, Tang & Yue, "Position domain
nonlinear PD control for contour tracking of robotic manipulator", Robotics and
Computer-Integrated Manufacturing 51, 2018) controls one joint, the master, in time and the
others, the slaves, as functions of the master's measured position: a master that lags drags
its slaves' references along, and the error across the path shrinks.

The law has the reference at the present instant only (``q_d, qd_d, qdd_d``, as every law of the
registry; goals and nodes give no more), so the master's position is measured in its
reference's own time ``sigma``: the instant at which the master's reference is where the
master is, ``q_m,d(sigma) = q_m``. To first order in the master's error

    ``delta = sigma - t = v (q_m - q_m,d) / (v^2 + v0^2)``,  ``v = qd_m,d``,

where ``v0`` (:data:`GAIN_V_REST`) returns the law to the time domain as the master's reference
comes to rest (``delta -> 0``; for ``|v| >> v0``, ``delta = (q_m - q_m,d) / v``). The slaves'
reference at the master's position is the reference's Taylor expansion to second order in
``delta``: ``q_s,d(sigma) = q_s,d + qd_s,d delta + qdd_s,d delta^2 / 2``,
``dq_s,d/dsigma = qd_s,d + qdd_s,d delta``. The master's measured rate in ``sigma`` is
``sigma_dot = 1 + w (qd_m - v_s) / v_s`` (``v_s = qd_m,d(sigma)``, ``w = v_s^2 / (v_s^2 + v0^2)``),
held in ``[SIGMA_DOT_MIN, 1 / SIGMA_DOT_MIN]`` (the guard of a master near rest or reversing
against its reference), and a slave's position-domain derivative is ``q' = qd / sigma_dot``.

The slaves run Eq. (3.44) on the position-domain errors

    ``e_s = q_s,d(sigma) - q_s``,  ``e_s' = dq_s,d/dsigma - qd_s / sigma_dot``,
    ``tau_s = Kp e_s + Kd e_s' + Ks sat((lambda e_s + e_s') / phi)``;

the master runs Eq. (3.44) in time. Derivatives are taken with respect to the master's position
expressed in its reference's time, ``d/dsigma = qd_m,d(sigma) d/dq_m``: Ouyang's
position-domain derivative gain is ``Kd`` times the master's reference speed, so one set of gains
(the thesis's, in their units) serves both domains and every speed of the master, and at the
reference (``sigma_dot = 1``) the slaves' gains are the time-domain law's.

The master is the joint whose reference moves fastest, its speed weighted by its stiffness (``Kp + Ks
lambda / phi``), chosen anew per segment: another joint takes over when its weighted speed exceeds the
master's by :data:`SWITCH_RATIO` (the master's index is the law's state, so the choice does not flicker
between two joints of nearly equal speed). The weight keeps a light joint from mastering a heavy one:
a slave feeds back ``k_s (qd_s,d / qd_m,d) e_m`` of the master's error, at most ``k_m e_m`` so weighted;
unweighted, the UR5's wrists (``Kp`` 43-633) mastered its shoulder and elbow (``Kp`` 2131-8037) and the
real-time margin fell from x2.05-2.45 to x0.34-1.36 (``docs/explanation/position-domain.md``). No joint
of the circle or the ellipse moves monotonically over the whole contour; the master does over each of
its segments, and is far from its turning points there.
:func:`error_map` is the law's linearisation for the stability check; the docs derive it
(``docs/explanation/position-domain.md``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numba import njit

from ..kernels.options import ALLOCATION_FREE
from ..robots.base import FloatArray, Manipulator
from .laws import GAIN_KD, GAIN_KP, THESIS_ROWS, pd_linear_gains, pdsmc_linear_gains
from .registry import KD, KP, KS, LAM, PHI, GainSpec, LawEntry

PD_POS = 7
PDSMC_POS = 8
PDSMC_VIRTUAL = 9
"""Codes of the compiled forms (:func:`pdsmc_ros.control.law.law_torque`); ``PDSMC_VIRTUAL``, the
virtual master's variant, is registered by the comparison only (``bench/position_domain.py``)."""

GAIN_V_REST = GainSpec("v_rest", "master reference speed v0 below which the position domain law returns to the "
                       "time domain (delta = v e_m / (v^2 + v0^2))", "rad/s", per_joint=False, lower_open=True,
                       neutral=1.0, start=0.05)
POSITION_ROWS = (*THESIS_ROWS, GAIN_V_REST)
V_REST = len(THESIS_ROWS)
"""Row of ``v0`` in the position domain laws' gain matrix (after the thesis's rows)."""

V_REST_PRESET = 0.05
"""``v0`` (rad/s) of the presets: a twentieth of the slowest thesis contour's peak joint speed (the
serial arm's circle, about 1 rad/s), so the law is in the position domain wherever the
master moves and in the time domain at rest (a goal's start and end, a hold)."""
SIGMA_DOT_MIN = 0.8
"""The guard of the measured master rate: ``sigma_dot`` held in ``[0.8, 1.25]``, so a slave's
position-domain derivative ``qd / sigma_dot`` is at most 1.25 times its time-domain value (a master
stalled, reversing against its reference, or measured with noise near rest)."""
SWITCH_RATIO = 1.25
"""A joint becomes the master when its stiffness-weighted reference speed exceeds the master's by this factor."""


@njit(cache=True, inline="always")
def _clamp(x, lo, hi):  # noqa: ANN001, ANN202
    return lo if x < lo else (hi if x > hi else x)


@njit(cache=True, inline="always")
def stiffness(g, i):  # noqa: ANN001, ANN201
    """Joint ``i``'s stiffness inside the boundary layer, ``Kp + Ks lambda / phi`` (Eq. 3.44 linear; ``Kp``
    for the PD, whose ``ks`` row is 0): the weight of its reference speed in the master's choice."""
    return g[KP, i] + g[KS, i] * g[LAM, i] / g[PHI, i]


@njit(cache=True, inline="always")
def master_joint(g, qd_ref, state, n):  # noqa: ANN001, ANN201
    """The master of this segment (0-based): the joint of the largest ``k_i |qd_i,d|`` (``k_i`` its
    :func:`stiffness`), kept until another's is :data:`SWITCH_RATIO` times larger; ``state[0, 0]`` holds it
    (plus one, 0: none yet). Weighted so, a slave's stiffness on the master's error, ``k_s |qd_s,d / qd_m,d|``,
    is at most the master's own ``k_m``: a light joint (a wrist) never drags a heavy one's reference."""
    best = 0
    for i in range(1, n):
        if stiffness(g, i) * abs(qd_ref[i]) > stiffness(g, best) * abs(qd_ref[best]):
            best = i
    m = int(state[0, 0]) - 1
    if m < 0 or m >= n or stiffness(g, best) * abs(qd_ref[best]) > SWITCH_RATIO * stiffness(g, m) * abs(qd_ref[m]):
        m = best
        state[0, 0] = m + 1.0
    return m


@njit(cache=True, inline="always")
def _pdsmc_joint(g, e, ed, i):  # noqa: ANN001, ANN202
    """Eq. (3.44) of joint ``i`` on the errors ``e``, ``ed`` (time or position domain)."""
    s = _clamp((g[LAM, i] * e + ed) / g[PHI, i], -1.0, 1.0)
    return g[KP, i] * e + g[KD, i] * ed + g[KS, i] * s


@njit(**ALLOCATION_FREE)
def position_domain(g, q, qd, q_ref, qd_ref, qdd_ref, tau, n, state, virtual):  # noqa: ANN001, ANN201, PLR0913
    """Position domain PD-SMC into ``tau`` (PD when the ``ks`` row is 0); module docstring.

    ``virtual``: the master is the reference's own time parameter ``sigma`` estimated from every joint
    (``delta`` the least-squares shift of the reference onto the measured joints,
    ``sum qd_d (q - q_d) / (|qd_d|^2 + v0^2)``), every joint a slave in its position domain, and the
    virtual master's own error in time, ``t - sigma = -delta`` (rate ``1 - sigma_dot``), fed back
    along the path's tangent ``dq_d/dsigma`` through each joint's gains; else the master of
    :func:`master_joint`, in time.
    """
    v0 = g[V_REST, 0]
    if virtual:
        num = 0.0
        den = v0 * v0
        for i in range(n):
            num += qd_ref[i] * (q[i] - q_ref[i])
            den += qd_ref[i] * qd_ref[i]
        delta = num / den
        num = 0.0
        den = v0 * v0
        for i in range(n):
            vs = qd_ref[i] + qdd_ref[i] * delta
            num += vs * (qd[i] - vs)
            den += vs * vs
        rate = _clamp(1.0 + num / den, SIGMA_DOT_MIN, 1.0 / SIGMA_DOT_MIN)
        m = -1
    else:
        m = master_joint(g, qd_ref, state, n)
        v = qd_ref[m]
        delta = v * (q[m] - q_ref[m]) / (v * v + v0 * v0)
        vs = v + qdd_ref[m] * delta
        rate = _clamp(1.0 + vs * (qd[m] - vs) / (vs * vs + v0 * v0), SIGMA_DOT_MIN, 1.0 / SIGMA_DOT_MIN)
    for i in range(n):
        if i == m:  # the master, in time
            tau[i] = _pdsmc_joint(g, q_ref[i] - q[i], qd_ref[i] - qd[i], i)
            continue
        # a slave, in the master's position domain
        vs = qd_ref[i] + qdd_ref[i] * delta
        e = q_ref[i] + qd_ref[i] * delta + 0.5 * qdd_ref[i] * delta * delta - q[i]
        ed = vs - qd[i] / rate
        if virtual:  # the virtual master's own error in time, t - sigma = -delta, along the path's tangent
            e -= vs * delta
            ed += vs * (1.0 - rate)
        tau[i] = _pdsmc_joint(g, e, ed, i)


def error_map(qd_ref: FloatArray, qdd_ref: FloatArray, v0: float,
              weights: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """The law linearised at the reference: the errors it feeds back are ``E e`` and ``E edot + G e``
    in place of the time-domain ``e = q_d - q`` and ``edot``, so ``tau = Kp E e + Kd (E edot + G e) + ...``.

    With ``a = v / (v^2 + v0^2)`` (``v = qd_m,d``; ``1 / v`` for ``|v| >> v0``), ``delta = -a e_m`` to
    first order: a slave's error is ``e_s - qd_s,d a e_m`` (``E``: the identity with its master column's
    slave entries ``-a qd_s,d``; the master's row is its own). A slave's position-domain derivative
    ``dq_s,d/dsigma - qd_s / sigma_dot`` moves with ``delta`` through the reference's acceleration and
    with ``sigma_dot`` through the master's: ``G`` has the master column's slave entries
    ``-a (qdd_s,d - a qd_s,d qdd_m,d)``, for ``|v| >> v0`` ``-v q_s,d''`` (the slave's reference curvature
    in the master's position domain, ``q_s,d'' = (qdd_s,d - q_s,d' qdd_m,d) / v^2``). ``sigma_dot`` is 1 at
    the reference, inside its guard. The master is the joint of the largest ``weights_i |qd_i,d|``
    (:func:`master_joint`: the joints' stiffness; None: equal weights), the hysteresis of
    :data:`SWITCH_RATIO` left out.
    """
    qd_ref = np.asarray(qd_ref, dtype=float)
    qdd_ref = np.asarray(qdd_ref, dtype=float)
    n = qd_ref.shape[0]
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=float)
    m = int(np.argmax(w * np.abs(qd_ref)))
    v = float(qd_ref[m])
    a = v / (v * v + v0 * v0)
    e_map, g_map = np.eye(n), np.zeros((n, n))
    e_map[:, m] = -a * qd_ref
    e_map[m, m] = 1.0
    g_map[:, m] = -a * (qdd_ref - a * qd_ref * qdd_ref[m])
    g_map[m, m] = 0.0
    return e_map, g_map


def pd_pos_linear_gains(g: FloatArray, smc_model: FloatArray, mass: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The PD's gains (Eq. 3.4) on the position-domain errors (:func:`error_map` maps them to the
    time-domain errors')."""
    return pd_linear_gains(g, smc_model, mass)


def pdsmc_pos_linear_gains(g: FloatArray, smc_model: FloatArray, mass: FloatArray) -> tuple[FloatArray, FloatArray]:
    """PD-SMC's gains inside the boundary layer (Eq. 3.44) on the position-domain errors."""
    return pdsmc_linear_gains(g, smc_model, mass)


def law_error_map(g: FloatArray, qd_ref: FloatArray, qdd_ref: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:func:`error_map` with the law's ``v0`` (its gain matrix's :data:`V_REST` row) and master (the joints'
    stiffness ``Kp + Ks lambda / phi`` weighting their speeds, as :func:`master_joint` does)."""
    weights = np.array([stiffness(g, i) for i in range(len(qd_ref))])
    return error_map(qd_ref, qdd_ref, float(g[V_REST, 0]), weights)


def v_rest_preset(source: Mapping[str, FloatArray], model: Manipulator,  # noqa: ARG001
                  q0: FloatArray) -> dict[str, FloatArray]:  # noqa: ARG001
    """``v0`` of the presets (:data:`V_REST_PRESET`); the other gains are the time-domain law's."""
    return {"v_rest": np.array([V_REST_PRESET])}


PD_POS_LAW = LawEntry("pd_pos", "PD (pos.)", (GAIN_KP, GAIN_KD, GAIN_V_REST),
                      equation="Eq. (3.4) in the master's position domain (Ouyang et al. 2015)", code=PD_POS,
                      linear_gains=pd_pos_linear_gains, rows=POSITION_ROWS, state_size=1, presets_from="pd",
                      derive_presets=v_rest_preset, error_map=law_error_map)
PDSMC_POS_LAW = LawEntry("pdsmc_pos", "PD-SMC (pos.)", POSITION_ROWS,
                         equation="Eq. (3.44) in the master's position domain (Ouyang et al. 2015)", code=PDSMC_POS,
                         linear_gains=pdsmc_pos_linear_gains, rows=POSITION_ROWS, state_size=1,
                         presets_from="pdsmc", derive_presets=v_rest_preset, error_map=law_error_map)


def transformed_dynamics(model: Manipulator, q: FloatArray, dq: FloatArray, ddq: FloatArray,
                         rate: float, accel: float) -> FloatArray:
    """The arm's torque (Eq. 4.1) for a motion written in a master coordinate ``p``.

    With ``q' = dq/dp``, ``q'' = d^2q/dp^2`` and the master's ``p_dot = rate``, ``p_ddot = accel``,
    ``qd = q' p_dot`` and ``qdd = q'' p_dot^2 + q' p_ddot``; ``C`` is linear in the velocity, so

        ``tau = Mbar (q'' p_dot^2 + q' p_ddot) + p_dot^2 C(q, q') q' + p_dot B q' + G(q)``

    (for the master itself, ``p = q_m``: ``q_m' = 1``, ``q_m'' = 0``: the position domain dynamics of
    Ouyang et al.'s PDC, derived here, not copied).
    """
    q, dq, ddq = (np.asarray(x, dtype=float) for x in (q, dq, ddq))
    mass = model.mass_matrix(q)
    return (mass @ (ddq * rate * rate + dq * accel) + rate * rate * (model.coriolis_matrix(q, dq) @ dq)
            + rate * model.B * dq + model.gravity(q))
