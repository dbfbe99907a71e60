"""Benchmark: controller period jitter and missed deadlines in real-time mode.

Runs the four nodes over DDS in real time (wall-clock paced, no lockstep) on the
parallel arm's circle at the given rate (1 kHz by default: the serial arm's
thesis gains need >= 8.4 kHz, the five-bar's are stable from about 0.5 kHz), then
reads the controller's achieved periods from the bag (``/pdsmc/controller_timing``)
with the same analysis code as ``pdsmc analyze``.

Last line: ``realtime_rate_hz=R jitter_p50_us=A jitter_p99_us=B missed_pct=C``.

Usage: python bench/realtime.py [--rate 1000] [--duration-factor 0.5] [--compose NODES [--intra-process]]
       [--busy-wait S] [--nice N]   (inside the venv)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pdsmc_ros.analysis import controller_timing  # noqa: E402
from pdsmc_ros.bagio import read_run  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=1000.0, help="control rate in Hz (default 1000)")
    parser.add_argument("--duration-factor", type=float, default=0.5,
                        help="fraction of the 10 s circle to run (default 0.5)")
    parser.add_argument("--compose", default="",
                        help="nodes to run in one process (run_experiment.sh --compose), e.g. plant,controller")
    parser.add_argument("--intra-process", action="store_true",
                        help="with --compose: hand messages between the composed nodes without DDS")
    parser.add_argument("--busy-wait", type=float, default=None,
                        help="seconds of each period busy-waited before the tick (node parameter busy_wait; "
                             "default 0.0002)")
    parser.add_argument("--nice", type=int, default=None,
                        help="niceness of the plant and the controller (run_experiment.sh --nice; negative needs root)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "realtime"
        cmd = ["bash", str(ROOT / "scripts" / "run_experiment.sh"), "--robot", "parallel_5r",
               "--contour", "circle", "--controller", "pdsmc", "--mode", "realtime",
               "--rate", f"{args.rate:g}", "--duration-factor", f"{args.duration_factor:g}",
               "--param", f"sample_rate:={args.rate / 2:g}", "--out", str(out), "--timeout", "600"]
        if args.compose:
            cmd += ["--compose", args.compose]
        if args.intra_process:
            cmd += ["--intra-process"]
        if args.busy_wait is not None:
            cmd += ["--param", f"busy_wait:={args.busy_wait:g}"]
        if args.nice is not None:
            cmd += ["--nice", str(args.nice)]
        if subprocess.run(cmd, env=os.environ.copy()).returncode != 0:
            print("bench/realtime.py: error: the real-time run failed (see the messages above)", file=sys.stderr)
            return 1
        run = read_run(out)
        timing = controller_timing(out, 1.0 / args.rate)
    if timing is None:
        print("bench/realtime.py: error: the bag holds no controller timing", file=sys.stderr)
        return 1
    print(f"controller ticks: {timing['ticks']}, mean period {1e6 * timing['period_mean_s']:.1f} us "
          f"(nominal {1e6 / args.rate:.1f} us)")
    print(f"jitter |period - nominal|: p50 {1e6 * timing['jitter_p50_s']:.1f} us, "
          f"p99 {1e6 * timing['jitter_p99_s']:.1f} us, max {1e6 * timing['jitter_max_s']:.1f} us")
    print(f"missed deadlines: {timing['missed_deadlines']} ({timing['missed_pct']:.3f} %); "
          f"plant steps recorded: {run.counts.get('/joint_states', 0)}")
    print(f"realtime_rate_hz={args.rate:g} jitter_p50_us={1e6 * timing['jitter_p50_s']:.1f} "
          f"jitter_p99_us={1e6 * timing['jitter_p99_s']:.1f} missed_pct={timing['missed_pct']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
