"""Benchmark: the compiled closed loop against the same maths unrolled by hand (issue 18).

For each thesis arm (the serial 3R and the five-bar, circle, PD-SMC at 10 kHz) it runs

- the production loop, :func:`pdsmc_ros.sim.loop.closed_loop` (what ``simulate`` runs), and
- a reference written here for that one arm: the same arithmetic in the same order in one
  function -- the arm's scalar terms and solve (the kernels' own), then RK4 and the law with
  every loop over the joints unrolled into scalar locals, no dispatch, no scratch array: what
  the generic loop (any robot, any law, arrays of n joints) costs over a hand-fused one,

checks that both give the same samples bit for bit, and prints steps per second and their
ratio. Target: production within 1.5x of the unrolled loop for both arms.

Last line: ``serial_3r_ratio=X parallel_5r_ratio=Y``.

Usage: python bench/kernel.py [--repeats 7]   (inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np
from numba import njit

from pdsmc_ros.control import ControlLaw
from pdsmc_ros.control.registry import KD, KP, KS, LAM, PHI
from pdsmc_ros.robots import parallel_5r_kernels as five_bar
from pdsmc_ros.robots import serial_3r as serial
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim.loop import closed_loop
from pdsmc_ros.sim.simulator import _reference_samples


# --------------------------------------------------------------------------- #
# The serial 3R, unrolled: its scalar terms and Cholesky solve (serial_3r's, shared
# with the production loop), RK4 and the law in scalars, one function
# --------------------------------------------------------------------------- #
@njit(cache=True)
def _serial_accel(p, q0, q1, q2, w0, w1, w2, t0, t1, t2):  # noqa: ANN001, ANN202, PLR0913
    """Eq. (4.1) for the 3R arm: ``qdd`` as three floats (the arm's scalar terms and solve)."""
    k00, k01, k02, k11, k12, k22, b0, b1, b2 = serial._terms(p, q0, q1, q2, w0, w1, w2)
    return serial._solve(k00, k01, k02, k11, k12, k22, t0 - b0 - p[21] * w0, t1 - b1 - p[22] * w1,
                         t2 - b2 - p[23] * w2)


@njit(cache=True)
def _sat(s):  # noqa: ANN001, ANN202
    if s > 1.0:
        return 1.0
    if s < -1.0:
        return -1.0
    return s


@njit(cache=True)
def serial_pdsmc_loop(p, g, q_start, refs, h, every, out_q, out_qd, out_tau):  # noqa: ANN001, ANN201, PLR0913, PLR0915
    """PD-SMC (Eq. 3.44) on the 3R arm with RK4 (sim.rk4), all in scalars."""
    q0, q1, q2 = q_start[0], q_start[1], q_start[2]
    v0 = v1 = v2 = 0.0
    steps = refs.shape[0] - 1
    half = 0.5 * h
    sixth = h / 6.0
    for k in range(steps + 1):
        e0 = refs[k, 0, 0] - q0
        e1 = refs[k, 0, 1] - q1
        e2 = refs[k, 0, 2] - q2
        f0 = refs[k, 1, 0] - v0
        f1 = refs[k, 1, 1] - v1
        f2 = refs[k, 1, 2] - v2
        t0 = g[KP, 0] * e0 + g[KD, 0] * f0 + g[KS, 0] * _sat((g[LAM, 0] * e0 + f0) / g[PHI, 0])
        t1 = g[KP, 1] * e1 + g[KD, 1] * f1 + g[KS, 1] * _sat((g[LAM, 1] * e1 + f1) / g[PHI, 1])
        t2 = g[KP, 2] * e2 + g[KD, 2] * f2 + g[KS, 2] * _sat((g[LAM, 2] * e2 + f2) / g[PHI, 2])
        if k % every == 0:
            j = k // every
            out_q[j, 0], out_q[j, 1], out_q[j, 2] = q0, q1, q2
            out_qd[j, 0], out_qd[j, 1], out_qd[j, 2] = v0, v1, v2
            out_tau[j, 0], out_tau[j, 1], out_tau[j, 2] = t0, t1, t2
        if k == steps:
            break
        a10, a11, a12 = _serial_accel(p, q0, q1, q2, v0, v1, v2, t0, t1, t2)
        u0, u1, u2 = v0 + half * a10, v1 + half * a11, v2 + half * a12
        a20, a21, a22 = _serial_accel(p, q0 + half * v0, q1 + half * v1, q2 + half * v2, u0, u1, u2, t0, t1, t2)
        r0, r1, r2 = v0 + half * a20, v1 + half * a21, v2 + half * a22
        a30, a31, a32 = _serial_accel(p, q0 + half * u0, q1 + half * u1, q2 + half * u2, r0, r1, r2, t0, t1, t2)
        z0, z1, z2 = v0 + h * a30, v1 + h * a31, v2 + h * a32
        a40, a41, a42 = _serial_accel(p, q0 + h * r0, q1 + h * r1, q2 + h * r2, z0, z1, z2, t0, t1, t2)
        q0 = q0 + sixth * (v0 + 2.0 * u0 + 2.0 * r0 + z0)
        q1 = q1 + sixth * (v1 + 2.0 * u1 + 2.0 * r1 + z1)
        q2 = q2 + sixth * (v2 + 2.0 * u2 + 2.0 * r2 + z2)
        v0, v1, v2 = (v0 + sixth * (a10 + 2.0 * a20 + 2.0 * a30 + a40),
                      v1 + sixth * (a11 + 2.0 * a21 + 2.0 * a31 + a41),
                      v2 + sixth * (a12 + 2.0 * a22 + 2.0 * a32 + a42))


# --------------------------------------------------------------------------- #
# The five-bar, unrolled: its geometry, scalar terms and 2 x 2 solve (the kernels'
# own), RK4 and the law in scalars, one function
# --------------------------------------------------------------------------- #
@njit(cache=True)
def _five_bar_accel(p, geo, q0, q1, w0, w1, t0, t1):  # noqa: ANN001, ANN202, PLR0913
    """Eq. (4.1) for the five-bar's reduced model: ``qdd`` as two floats."""
    five_bar._geometry(p, (q0, q1), (w0, w1), geo)
    k00, m01, k11, b0, b1 = five_bar._terms(p, geo)
    return five_bar._solve(k00, m01, k11, t0 - b0 - p[23] * w0, t1 - b1 - p[24] * w1)


@njit(cache=True)
def five_bar_pdsmc_loop(p, g, q_start, refs, h, every, out_q, out_qd, out_tau):  # noqa: ANN001, ANN201, PLR0913
    """PD-SMC (Eq. 3.44) on the five-bar with RK4 (sim.rk4), in scalars."""
    geo = np.empty(five_bar.GEOMETRY_SIZE)
    q0, q1 = q_start[0], q_start[1]
    v0 = v1 = 0.0
    steps = refs.shape[0] - 1
    half = 0.5 * h
    sixth = h / 6.0
    for k in range(steps + 1):
        e0 = refs[k, 0, 0] - q0
        e1 = refs[k, 0, 1] - q1
        f0 = refs[k, 1, 0] - v0
        f1 = refs[k, 1, 1] - v1
        t0 = g[KP, 0] * e0 + g[KD, 0] * f0 + g[KS, 0] * _sat((g[LAM, 0] * e0 + f0) / g[PHI, 0])
        t1 = g[KP, 1] * e1 + g[KD, 1] * f1 + g[KS, 1] * _sat((g[LAM, 1] * e1 + f1) / g[PHI, 1])
        if k % every == 0:
            j = k // every
            out_q[j, 0], out_q[j, 1] = q0, q1
            out_qd[j, 0], out_qd[j, 1] = v0, v1
            out_tau[j, 0], out_tau[j, 1] = t0, t1
        if k == steps:
            break
        a10, a11 = _five_bar_accel(p, geo, q0, q1, v0, v1, t0, t1)
        u0, u1 = v0 + half * a10, v1 + half * a11
        a20, a21 = _five_bar_accel(p, geo, q0 + half * v0, q1 + half * v1, u0, u1, t0, t1)
        r0, r1 = v0 + half * a20, v1 + half * a21
        a30, a31 = _five_bar_accel(p, geo, q0 + half * u0, q1 + half * u1, r0, r1, t0, t1)
        z0, z1 = v0 + h * a30, v1 + h * a31
        a40, a41 = _five_bar_accel(p, geo, q0 + h * r0, q1 + h * r1, z0, z1, t0, t1)
        q0 = q0 + sixth * (v0 + 2.0 * u0 + 2.0 * r0 + z0)
        q1 = q1 + sixth * (v1 + 2.0 * u1 + 2.0 * r1 + z1)
        v0, v1 = (v0 + sixth * (a10 + 2.0 * a20 + 2.0 * a30 + a40),
                  v1 + sixth * (a11 + 2.0 * a21 + 2.0 * a31 + a41))


UNROLLED = {"serial_3r": serial_pdsmc_loop, "parallel_5r": five_bar_pdsmc_loop}


def best_rate(run, steps: int, repeats: int) -> float:  # noqa: ANN001
    """Steps per second of ``run()``, best of ``repeats``."""
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return steps / best


def measure(robot: str, repeats: int) -> tuple[float, float, bool]:
    """Production and unrolled steps/s of ``robot``'s circle under PD-SMC; identical samples?"""
    spec = make_run(robot, "circle", "pdsmc")
    _, refs = _reference_samples(spec)
    plant = spec.robot_model()
    law = ControlLaw.from_spec(spec)
    h = 1.0 / spec.rate
    every = spec.sample_every
    steps = refs.shape[0] - 1
    q_start = np.array(refs[0, 0])
    count = steps // every + 1
    outs = tuple(np.empty((count, plant.n)) for _ in range(3))
    p = plant.pack()

    def unrolled() -> None:
        UNROLLED[robot](p, law.gains, q_start, refs, h, every, *outs)

    def production() -> tuple[np.ndarray, ...]:
        return closed_loop(plant, law, q_start, refs, h, every)

    unrolled()
    same = all(np.array_equal(a, b) for a, b in zip(production(), outs, strict=True))
    # alternating, best of each: this machine's speed drifts within seconds
    fast = slow = 0.0
    for _ in range(repeats):
        fast = max(fast, best_rate(unrolled, steps, 1))
        slow = max(slow, best_rate(production, steps, 1))
    return slow, fast, same


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    ratios = {}
    for robot in UNROLLED:
        slow, fast, same = measure(robot, args.repeats)
        ratios[robot] = fast / slow
        print(f"{robot} circle PD-SMC, 10 kHz: production {slow:,.0f} steps/s, unrolled {fast:,.0f} steps/s, "
              f"ratio x{fast / slow:.2f}; samples identical: {'yes' if same else 'NO'}", flush=True)
        if not same:
            print(f"error: {robot}: the unrolled loop's samples differ from the production loop's", file=sys.stderr)
            return 1
    print(" ".join(f"{robot}_ratio={ratio:.2f}" for robot, ratio in ratios.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
