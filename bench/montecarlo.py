"""Benchmark: the Monte Carlo engine (issue 18) -- task overhead, worker scaling, a 1,000-run table.

Prints, for the five-bar's circle (three controllers per drawn plant):
- the engine's per-task overhead: wall time of a batch of tasks on a 1-worker local cluster
  against the same tasks run in this process, per task;
- 1 worker against 2 workers (local clusters) on the same runs: the speed-up;
- the wall time of a ``--runs 1000`` Monte Carlo on 2 workers (``--runs`` to change).

Last line: ``overhead_ms_per_task=X speedup_2_workers=S montecarlo_1000_wall_s=W``.

Usage: python bench/montecarlo.py [--runs 1000] [--scaling-runs 40]   (inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import sys
import time

from pdsmc_ros.engine import dask_client, run_tasks
from pdsmc_ros.montecarlo import base_specs, load_uncertainty, run_sample

ROBOT, CONTOUR, CONTROLLERS = "parallel_5r", "circle", ("pd", "smc", "pdsmc")


def timed_cluster(workers: int, runs: int, seed: int = 1) -> float:
    """Wall time of ``runs`` Monte Carlo tasks on a local cluster of ``workers`` (kernels warmed first)."""
    specs = base_specs(ROBOT, CONTOUR, list(CONTROLLERS))
    spreads = load_uncertainty()
    with dask_client(None, workers) as client:
        # every worker compiles / loads its kernels before the clock starts
        list(run_tasks(client, run_sample, [(10_000 + i, seed, specs, spreads) for i in range(2 * workers)]))
        start = time.perf_counter()
        list(run_tasks(client, run_sample, [(i, seed, specs, spreads) for i in range(runs)]))
        return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--scaling-runs", type=int, default=40)
    args = parser.parse_args()
    specs = base_specs(ROBOT, CONTOUR, list(CONTROLLERS))
    spreads = load_uncertainty()
    run_sample(10_000, 1, specs, spreads)  # compile here too
    n = args.scaling_runs
    start = time.perf_counter()
    for i in range(n):
        run_sample(i, 1, specs, spreads)
    here = time.perf_counter() - start
    one = timed_cluster(1, n)
    overhead_ms = 1000.0 * (one - here) / n
    print(f"{n} tasks (a drawn plant x {len(CONTROLLERS)} controllers, {ROBOT} {CONTOUR}): in this process "
          f"{here:.2f} s ({1000 * here / n:.1f} ms a task), 1-worker cluster {one:.2f} s: overhead "
          f"{overhead_ms:.1f} ms a task", flush=True)
    two = timed_cluster(2, n)
    print(f"2-worker cluster {two:.2f} s: speed-up x{one / two:.2f} over 1 worker", flush=True)
    start = time.perf_counter()
    timed = timed_cluster(2, args.runs)
    total = time.perf_counter() - start
    print(f"{args.runs}-run Monte Carlo on 2 workers: {timed:.1f} s of runs, {total:.1f} s with the cluster's "
          "start and warm-up", flush=True)
    print(f"overhead_ms_per_task={overhead_ms:.1f} speedup_2_workers={one / two:.2f} "
          f"montecarlo_{args.runs}_wall_s={total:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
