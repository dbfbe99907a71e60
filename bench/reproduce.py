"""Benchmark: the whole in-process thesis matrix.

Prints the wall time of `pdsmc reproduce` (all runs of Tables 4.17-4.61, both cores) and the
simulated control steps per second; last line `matrix_wall_s=S runs=R`.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from pdsmc_ros.experiments.thesis.reproduce import run_reproduction  # noqa: E402


def main() -> int:
    start = time.perf_counter()
    rep = run_reproduction(readings=False)
    wall = time.perf_counter() - start
    steps = sum(r.steps for r in rep.results)
    cpu = sum(r.wall_s for r in rep.results)
    print(f"runs: {len(rep.results)}  control steps: {steps:,}")
    print(f"per-run time summed over workers: {cpu:.1f} s -> {steps / cpu:,.0f} steps/s per core")
    print(f"matrix_wall_s={wall:.1f} runs={len(rep.results)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
