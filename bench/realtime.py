"""Benchmark: controller period jitter and missed deadlines in real-time mode.

Runs the four nodes over DDS in real time (wall-clock paced, no lockstep) on the
parallel arm's circle at the given rate (1 kHz by default: the serial arm's
thesis gains need >= 8.4 kHz, the five-bar's are stable from about 0.5 kHz), then
reads the controller's achieved periods from the bag (``/pdsmc/controller_timing``)
with the same analysis code as ``pdsmc analyze``.

With no arrangement options it measures the four-process default and the
real-time arrangement: plant, controller and trajectory composed with
``--intra-process`` and ``busy_wait`` of a whole period (that process never
sleeps: it takes one core), the recorder apart. Last line, of the latter or of
the arrangement given: ``realtime_rate_hz=R jitter_p50_us=A jitter_p99_us=B missed_pct=C``.

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

from pdsmc_ros.bag.reader import read_run  # noqa: E402
from pdsmc_ros.thesis.analysis import controller_timing  # noqa: E402

REALTIME_LABEL = "plant, controller and trajectory composed intra-process, busy-waiting the whole period"


def realtime_options(rate: float) -> list[str]:
    """The ticking nodes in one process that never sleeps (one core), the recorder apart."""
    return ["--compose", "plant,controller,trajectory", "--intra-process", "--param", f"busy_wait:={1.0 / rate:g}"]


def measure(rate: float, factor: float, options: list[str]) -> dict | None:
    """One real-time run with run_experiment.sh ``options``; the controller's timing, or None."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "realtime"
        cmd = ["bash", str(ROOT / "scripts" / "run_experiment.sh"), "--robot", "parallel_5r",
               "--contour", "circle", "--controller", "pdsmc", "--mode", "realtime",
               "--rate", f"{rate:g}", "--duration-factor", f"{factor:g}",
               "--param", f"sample_rate:={rate / 2:g}", "--out", str(out), "--timeout", "600", *options]
        if subprocess.run(cmd, env=os.environ.copy()).returncode != 0:
            print("bench/realtime.py: error: the real-time run failed (see the messages above)", file=sys.stderr)
            return None
        run = read_run(out)
        timing = controller_timing(out, 1.0 / rate)
    if timing is None:
        print("bench/realtime.py: error: the bag holds no controller timing", file=sys.stderr)
        return None
    timing["plant_steps"] = run.counts.get("/joint_states", 0)
    return timing


def report(label: str, rate: float, timing: dict) -> None:
    print(f"{label}: controller ticks {timing['ticks']}, mean period {1e6 * timing['period_mean_s']:.1f} us "
          f"(nominal {1e6 / rate:.1f} us); jitter |period - nominal| p50 {1e6 * timing['jitter_p50_s']:.1f} us, "
          f"p99 {1e6 * timing['jitter_p99_s']:.1f} us, max {1e6 * timing['jitter_max_s']:.1f} us; "
          f"missed deadlines {timing['missed_deadlines']} ({timing['missed_pct']:.3f} %); "
          f"plant steps recorded {timing['plant_steps']}")


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
    options = []
    if args.compose:
        options += ["--compose", args.compose]
    if args.intra_process:
        options += ["--intra-process"]
    if args.busy_wait is not None:
        options += ["--param", f"busy_wait:={args.busy_wait:g}"]
    if args.nice is not None:
        options += ["--nice", str(args.nice)]
    if options:
        arrangements = [("as given", options)]
    else:  # the default and the real-time arrangement (docs/PERFORMANCE.md)
        arrangements = [("4 processes, defaults", []), (REALTIME_LABEL, realtime_options(args.rate))]
    results = []
    for label, opts in arrangements:
        timing = measure(args.rate, args.duration_factor, opts)
        if timing is None:
            return 1
        report(label, args.rate, timing)
        results.append((label, timing))
    label, timing = results[-1]
    print(f"last line: {label}")
    print(f"realtime_rate_hz={args.rate:g} jitter_p50_us={1e6 * timing['jitter_p50_s']:.1f} "
          f"jitter_p99_us={1e6 * timing['jitter_p99_s']:.1f} missed_pct={timing['missed_pct']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
