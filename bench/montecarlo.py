"""Benchmark: the Monte Carlo engine (issue 18) -- task overhead, worker scaling, a 1,000-run table.

Prints, for the five-bar's circle (three controllers per drawn plant):
- the engine's per-task overhead: wall time of a batch of tasks on one worker of a local
  2-worker cluster against the same tasks run in this process, per task;
- one worker against both on the same runs: the speed-up.
  Both in alternating rounds (medians), as this machine's speed drifts;
- the wall time of a ``--runs 1000`` Monte Carlo on 2 workers (``--runs`` to change).

Last line: ``overhead_ms_per_task=X speedup_2_workers=S montecarlo_1000_wall_s=W``.

Usage: python bench/montecarlo.py [--runs 1000] [--scaling-runs 20] [--rounds 5]   (inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

from pdsmc_ros.engine import dask_client
from pdsmc_ros.montecarlo import base_specs, load_uncertainty, run_sample

ROBOT, CONTOUR, CONTROLLERS = "parallel_5r", "circle", ("pd", "smc", "pdsmc")


def timed_tasks(client, runs: int, first: int, specs, spreads, workers=None) -> float:  # noqa: ANN001
    """Wall time of ``runs`` Monte Carlo tasks on ``client`` (on ``workers`` only, if given)."""
    start = time.perf_counter()
    futures = [client.submit(run_sample, first + i, 1, specs, spreads, workers=workers, pure=False)
               for i in range(runs)]
    client.gather(futures)
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--scaling-runs", type=int, default=20, help="tasks per round")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    specs = base_specs(ROBOT, CONTOUR, list(CONTROLLERS))
    spreads = load_uncertainty()
    run_sample(10_000, 1, specs, spreads)  # compile here too
    n = args.scaling_runs
    here, one, two = [], [], []
    with dask_client(None, 2) as client:
        addresses = sorted(client.scheduler_info()["workers"])
        # every worker loads its kernels before any clock starts
        client.gather([client.submit(run_sample, 10_000 + i, 1, specs, spreads, workers=[address], pure=False)
                       for i, address in enumerate(addresses)])
        # alternating rounds: this machine's speed drifts by +-25 % within minutes
        for r in range(args.rounds):
            first = 1_000 * r
            start = time.perf_counter()
            for i in range(n):
                run_sample(first + i, 1, specs, spreads)
            here.append(time.perf_counter() - start)
            one.append(timed_tasks(client, n, first, specs, spreads, workers=[addresses[0]]))
            two.append(timed_tasks(client, n, first, specs, spreads))
            print(f"round {r + 1}: {n} tasks in this process {here[-1]:.2f} s, on 1 worker {one[-1]:.2f} s, "
                  f"on 2 workers {two[-1]:.2f} s (x{one[-1] / two[-1]:.2f})", flush=True)
    overhead_ms = 1000.0 * statistics.median((o - h) / n for o, h in zip(one, here, strict=True))
    speedup = statistics.median(o / t for o, t in zip(one, two, strict=True))
    print(f"{ROBOT} {CONTOUR}, a task = a drawn plant x {len(CONTROLLERS)} controllers: "
          f"{1000 * statistics.median(here) / n:.1f} ms in this process; engine overhead (median of rounds) "
          f"{overhead_ms:.1f} ms a task; 2 workers x{speedup:.2f} over 1 (median of per-round ratios)", flush=True)
    start = time.perf_counter()
    with dask_client(None, 2) as client:
        timed = timed_tasks(client, args.runs, 0, specs, spreads)
    total = time.perf_counter() - start
    print(f"{args.runs}-run Monte Carlo on 2 workers: {timed:.1f} s of runs, {total:.1f} s with the cluster's "
          "start", flush=True)
    print(f"overhead_ms_per_task={overhead_ms:.1f} speedup_2_workers={speedup:.2f} "
          f"montecarlo_{args.runs}_wall_s={total:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
