"""Benchmark: the memory of a long run (issue 28) -- 3,600 s at 1 kHz in-process, with and without samples.

Runs the UR5 on its circle with PD-SMC at its 1 kHz (statistics at 500 Hz), the contour slowed to last
``--seconds`` (default 3,600), each in a fresh process so that its peak resident memory is its own:
``simulate(spec, keep_samples=False)`` (the run in stretches, statistics only) and, unless
``--no-samples-run``, ``simulate(spec)`` (every sample kept). Prints each run's wall time, peak
resident memory (``ru_maxrss``) and contour mean, and whether the two runs' statistics are equal.

Last line: ``metrics_only_peak_mb=A with_samples_peak_mb=B metrics_only_wall_s=C equal=D``.

Usage: python bench/long_run.py [--seconds 3600] [--no-samples-run]   (inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

CHILD = """
import dataclasses, json, resource, sys, time
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate
seconds, keep = float(sys.argv[1]), sys.argv[2] == "keep"
spec = make_run("ur5", "circle", "pdsmc")
spec = dataclasses.replace(spec, duration_factor=seconds / spec.contour_model().duration)
start = time.perf_counter()
result = simulate(spec, keep_samples=keep)
wall = time.perf_counter() - start
print(json.dumps({"wall_s": wall, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "steps": result.steps, "metrics": result.metrics.as_dict()}))
"""


def run(seconds: float, keep: bool) -> dict:  # type: ignore[type-arg]
    proc = subprocess.run([sys.executable, "-c", CHILD, str(seconds), "keep" if keep else "lean"],
                          capture_output=True, text=True, timeout=3600, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3600.0, help="the run's length, s (default 3600)")
    parser.add_argument("--no-samples-run", action="store_true", help="skip the run that keeps its samples")
    args = parser.parse_args()
    lean = run(args.seconds, keep=False)
    print(f"metrics only: {lean['steps']:,} steps in {lean['wall_s']:.1f} s, peak {lean['peak_mb']:.0f} MB, "
          f"contour mean {lean['metrics']['contour_mean']:.6e} m", flush=True)
    full = {"peak_mb": float("nan")}
    equal = "n/a"
    if not args.no_samples_run:
        full = run(args.seconds, keep=True)
        equal = str(full["metrics"] == lean["metrics"]).lower()
        print(f"with samples: {full['steps']:,} steps in {full['wall_s']:.1f} s, peak {full['peak_mb']:.0f} MB, "
              f"contour mean {full['metrics']['contour_mean']:.6e} m; statistics equal: {equal}", flush=True)
    print(f"metrics_only_peak_mb={lean['peak_mb']:.0f} with_samples_peak_mb={full['peak_mb']:.0f} "
          f"metrics_only_wall_s={lean['wall_s']:.1f} equal={equal}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
