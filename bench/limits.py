"""Benchmark: what the torque clamp and the divergence check cost the compiled closed loop (issue 29).

For each thesis arm (circle, PD-SMC at 10 kHz) it runs, in one process and alternating so
that a loaded machine slows both alike:

- the production loop (:mod:`pdsmc_ros.sim.loop`: every step the state's check,
  :func:`pdsmc_ros.sim.divergence.watch`, and the clamp to the effort limits through
  :func:`~pdsmc_ros.control.soft_limits.soft_limit` with unknown velocity limits), and
- the same loop without them, written here as it was before issue 29 (the same law, RK4 and
  sampling code),

checks that both give the same samples bit for bit (the thesis arms' limits are never reached),
and prints steps per second (best of the repeats) and the time ratio, best and median.

Last line: ``serial_3r_time=X parallel_5r_time=Y`` (production time / loop without the checks).

Usage: python bench/limits.py [--repeats 30]   (inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable

import numpy as np
from numba import njit

from pdsmc_ros.control import ControlLaw
from pdsmc_ros.control.law import law_torque
from pdsmc_ros.control.soft_limits import effort_only_table
from pdsmc_ros.robots import compiled as robot_compiled
from pdsmc_ros.robots.parallel_5r_kernels import PARALLEL_5R
from pdsmc_ros.robots.serial_3r import SERIAL_3R
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim.divergence import DivergenceCheck
from pdsmc_ros.sim.loop import _CLOSED_LOOPS
from pdsmc_ros.sim.rk4 import carve, rk4_advance
from pdsmc_ros.sim.simulator import _reference_samples


@njit(inline="always")
def _unchecked(kind, p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,  # noqa: ANN001, ANN202, PLR0913
               out_q, out_qd, out_tau, work, state):
    n = robot_compiled.size(kind, q0.shape[0])
    steps = refs.shape[0] - 1
    stages, rest = carve(work, n)
    q = q0.copy()
    qd = qd0.copy()
    tau = np.empty(n)
    for k in range(steps + 1):
        law_torque(code, gains, smc_model, model_kind, model_p, q, qd, refs[k, 0], refs[k, 1], refs[k, 2], tau,
                   work, n, state, h)
        if k % sample_every == 0:
            j = k // sample_every
            for i in range(n):
                out_q[j, i] = q[i]
                out_qd[j, i] = qd[i]
                out_tau[j, i] = tau[i]
        if k < steps:
            rk4_advance(kind, p, q, qd, tau, h, stages, rest)


@njit
def _unchecked_serial(p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,  # noqa: ANN001, ANN202, PLR0913
                      out_q, out_qd, out_tau, work, state):
    _unchecked(SERIAL_3R, p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,
               out_q, out_qd, out_tau, work, state)


@njit
def _unchecked_parallel(p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,  # noqa: ANN001, ANN202, PLR0913
                        out_q, out_qd, out_tau, work, state):
    _unchecked(PARALLEL_5R, p, code, gains, smc_model, model_kind, model_p, q0, qd0, refs, h, sample_every,
               out_q, out_qd, out_tau, work, state)


UNCHECKED = {SERIAL_3R: _unchecked_serial, PARALLEL_5R: _unchecked_parallel}


def measure(robot: str, repeats: int) -> tuple[float, float, float, float, bool]:
    """Steps per second without and with the checks (best), time ratios (best, median), same samples."""
    spec = make_run(robot, "circle", "pdsmc", rate=10000.0)
    _, refs = _reference_samples(spec)
    plant, law = spec.robot_model(), ControlLaw.from_spec(spec)
    kind, p = robot_compiled.pack(plant)
    n, every, h = plant.n, spec.sample_every, 1.0 / spec.rate
    rows = (refs.shape[0] - 1) // every + 1
    outs = [np.empty((rows, n)) for _ in range(3)]
    work = robot_compiled.workspace(n)
    setup = (p, law.code, law.gains, law.smc_model, law.model_kind, law.model_params)

    def unchecked() -> None:
        UNCHECKED[kind](*setup, refs[0, 0].copy(), np.zeros(n), refs, h, every, *outs, work, law.state)

    table = effort_only_table(plant.effort_limits, n)

    def production() -> None:
        check = DivergenceCheck.for_robot(plant)
        counts = np.zeros(n + 2, dtype=np.int64)
        _CLOSED_LOOPS[kind](*setup, refs[0, 0].copy(), np.zeros(n), refs, h, every, table,
                            check.bounds, check.first, check.at, counts, *outs, work, law.state, 0, 0)

    unchecked()
    before = [o.copy() for o in outs]
    production()
    same = all(np.array_equal(a, b) for a, b in zip(before, outs, strict=True))
    times: dict[Callable[[], None], list[float]] = {unchecked: [], production: []}
    for _ in range(repeats):
        for run in (unchecked, production):
            start = time.perf_counter()
            run()
            times[run].append(time.perf_counter() - start)
    steps = refs.shape[0] - 1
    old, new = np.array(times[unchecked]), np.array(times[production])
    return steps / old.min(), steps / new.min(), new.min() / old.min(), float(np.median(new / old)), same


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args()
    ratios = {}
    for robot in ("serial_3r", "parallel_5r"):
        old, new, best, median, same = measure(robot, args.repeats)
        ratios[robot] = best
        print(f"{robot} circle PD-SMC, 10 kHz: without the checks {old:,.0f} steps/s, with them {new:,.0f} "
              f"steps/s; time x{best:.3f} (best), x{median:.3f} (median of pairs); samples identical: "
              f"{'yes' if same else 'NO'}", flush=True)
        if not same:
            print(f"error: {robot}: the checked loop's samples differ from the unchecked loop's", file=sys.stderr)
            return 1
    print(" ".join(f"{robot}_time={ratio:.3f}" for robot, ratio in ratios.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
