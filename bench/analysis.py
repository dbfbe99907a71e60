"""Benchmark: analysis time of a 10 s parallel-arm bag (50,001 steps at 5 kHz).

Records the bag once over DDS (composed mode) into bags/bench-parallel-circle
if it is not there yet, then times `read_run` + `run_metrics` (what
`pdsmc analyze` does). Last line: ``analysis_s=S steps=N``. Target: S <= 2.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pdsmc_ros.bag.reader import read_run, run_metrics  # noqa: E402


def main() -> int:
    bag = ROOT / "bags" / "bench-parallel-circle"
    if not bag.exists():
        print(f"recording {bag} (10 s parallel circle, lockstep, composed) ...", flush=True)
        subprocess.run(["bash", str(ROOT / "scripts" / "run_experiment.sh"), "--robot", "parallel_5r",
                        "--contour", "circle", "--controller", "pdsmc", "--composed",
                        "--out", str(bag), "--timeout", "1800"], check=True)
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        run = read_run(bag)
        metrics = run_metrics(run)
        best = min(best, time.perf_counter() - start)
    print(f"bag: {bag} ({run.steps + 1} steps, complete={run.complete}), contour mean {metrics.contour_mean:.4e} m")
    print(f"analysis_s={best:.2f} steps={run.steps + 1}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
