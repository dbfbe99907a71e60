"""Benchmark: the Monte Carlo engine (issue 18) -- task overhead, worker scaling, a 1,000-run table.

Prints, for the five-bar's circle (three controllers per drawn plant):
- the engine's per-task overhead: wall time of a batch of tasks on one worker of a local
  2-worker cluster against the same tasks run in this process, per task;
- one worker against both on the same runs: the speed-up.
  Both in alternating rounds (medians), as this machine's speed drifts;
- the wall time of a ``--runs 1000`` Monte Carlo on 2 workers (``--runs`` to change).

Last line: ``overhead_ms_per_task=X speedup_2_workers=S montecarlo_1000_wall_s=W``.

``--profile N`` instead: where a task's time goes, N tasks in this process under cProfile -- the
compiled closed loop against the rest (set-up, samples, statistics, scores), and the largest items
of the rest. Last line: ``task_ms=X loop_share=Y``.

Usage: python bench/montecarlo.py [--runs 1000] [--scaling-runs 20] [--rounds 5] [--profile N]
(inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

from pdsmc_ros.experiments.montecarlo import base_specs, load_uncertainty, run_sample
from pdsmc_ros.sim.engine import dask_client, keep_freed_memory, run_tasks

ROBOT, CONTOUR, CONTROLLERS = "parallel_5r", "circle", ("pd", "smc", "pdsmc")


def timed_tasks(client, runs: int, first: int, specs, spreads, workers=None) -> float:  # noqa: ANN001
    """Wall time of ``runs`` Monte Carlo tasks on ``client`` (on ``workers`` only, if given), submitted as
    ``pdsmc montecarlo`` submits them (the engine's ``run_tasks``: its tasks set the worker's allocator up)."""
    start = time.perf_counter()
    for _ in run_tasks(client, run_sample, [(first + i, 1, specs, spreads) for i in range(runs)], workers=workers):
        pass
    return time.perf_counter() - start


def profile(tasks: int, specs, spreads) -> None:  # noqa: ANN001
    """Where ``tasks`` Monte Carlo tasks spend their time (cProfile, in this process)."""
    import cProfile
    import pstats

    profiler = cProfile.Profile()
    start, cpu = time.perf_counter(), time.process_time()
    profiler.enable()
    for i in range(tasks):
        run_sample(i, 1, specs, spreads)
    profiler.disable()
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    stats = pstats.Stats(profiler).stats  # type: ignore[attr-defined]
    by_name = {f"{func[0].rsplit('/', 2)[-1]}:{func[2]}": (calls, cumulative)
               for func, (_, calls, _, cumulative, _) in stats.items()}
    loop = sum(c for name, (_, c) in by_name.items() if name == "loop.py:closed_loop")
    task = by_name["montecarlo.py:run_sample"][1]
    print(f"{tasks} tasks ({len(specs)} runs each) in {wall:.2f} s ({cpu:.2f} s of CPU): {1000 * task / tasks:.1f} "
          f"ms a task, the compiled loop {100 * loop / task:.1f} %, the rest {1000 * (task - loop) / tasks:.1f} ms "
          "a task", flush=True)
    rest = ("simulator.py:_reference_samples", "simulator.py:_task_samples", "metrics.py:build_samples",
            "metrics.py:compute_metrics", "metrics.py:scores", "law.py:from_spec",
            "registry.py:make_robot", "montecarlo.py:sample_plant", "divergence.py:for_robot")
    for name in rest:
        if name in by_name:
            share = by_name[name][1] / task
            print(f"  {name:34s} {1000 * by_name[name][1] / tasks:7.2f} ms a task ({100 * share:.1f} %)")
    print(f"task_ms={1000 * task / tasks:.1f} task_cpu_ms={1000 * cpu / tasks:.1f} loop_share={loop / task:.3f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--scaling-runs", type=int, default=20, help="tasks per round")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--profile", type=int, default=0, help="profile this many tasks in process, nothing else")
    args = parser.parse_args()
    specs = base_specs(ROBOT, CONTOUR, list(CONTROLLERS))
    spreads = load_uncertainty()
    keep_freed_memory()  # as the engine's tasks do: the in-process figures are of the same allocator
    run_sample(10_000, 1, specs, spreads)  # compile here too
    if args.profile:
        profile(args.profile, specs, spreads)
        return 0
    n = args.scaling_runs
    here, one, two = [], [], []
    with dask_client(None, 2) as client:
        addresses = sorted(client.scheduler_info()["workers"])
        # every worker loads its kernels before any clock starts
        for i, address in enumerate(addresses):
            timed_tasks(client, 1, 10_000 + i, specs, spreads, workers=[address])
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
