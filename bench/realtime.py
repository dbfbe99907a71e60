"""Benchmark: controller period jitter and missed deadlines in real-time mode (issue 26).

Runs the nodes over DDS in real time (wall-clock paced, no lockstep) on the parallel arm's
circle at 2 kHz (the five-bar's PD-SMC gains are stable in real time from about 1.05 kHz), in two arrangements,
alternating, ``--runs`` times each (3 by default):

* four processes: plant, controller, trajectory and recorder each in its own process;
* composed: plant, controller and trajectory in one process with ``--intra-process``, the
  recorder apart.

Each run's controller periods come from the bag (``/pdsmc/controller_timing``, read with
the same code as ``pdsmc analyze``); the loop statistics of every ticking node (page faults
after warm-up among them) from its ``/diagnostics``. The nodes run with their defaults:
in real time ``thread_priority`` 50 (SCHED_FIFO), ``lock_memory`` on; ``--baseline`` runs
the settings before issue 26 instead (normal scheduling, memory not locked, and the composed
process busy-waiting the whole period, as it was kept then).

Last line (each figure the worst of its runs): ``four_process_p99_us=A
four_process_missed_pct=B composed_p99_us=C composed_missed_pct=D composed_max_us=E``
(p99 of |period - nominal|, missed deadlines in %, and the composed worst period).

Usage: python bench/realtime.py [--runs 3] [--rate 2000] [--duration-factor 0.5] [--baseline]
       [--param NAME:=VALUE ...]   (inside the venv)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from pdsmc_ros.bag.loop_statistics import bag_loop_statistics  # noqa: E402
from pdsmc_ros.experiments.analysis import controller_timing  # noqa: E402

COMPOSED = ["--compose", "plant,controller,trajectory", "--intra-process"]
BASELINE = ["--param", "thread_priority:=0", "--param", "lock_memory:=false"]


def worst_period(path: Path) -> float:
    """The longest achieved controller period in the bag (seconds)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    rows = []
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic == "/pdsmc/controller_timing"]
        for conn, _, raw in reader.messages(connections=conns):
            rows.append(np.asarray(reader.deserialize(raw, conn.msgtype).data))
    data = np.concatenate(rows).reshape(-1, 5)
    return float(data[1:, 1].max())


def measure(rate: float, factor: float, options: list[str]) -> dict[str, Any] | None:
    """One real-time run with run_experiment.sh ``options``; the controller's timing, or None."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "realtime"
        cmd = ["bash", str(ROOT / "scripts" / "run_experiment.sh"), "--robot", "parallel_5r",
               "--contour", "circle", "--controller", "pdsmc", "--mode", "realtime",
               "--rate", f"{rate:g}", "--duration-factor", f"{factor:g}",
               "--param", f"sample_rate:={rate / 2:g}", "--out", str(out), "--timeout", "600",
               # the five-bar's PD-SMC gains at 2 kHz have a stability margin of x1.9 with the real-time
               # loop's two periods of delay (the controller asks for x2 by default; at 1 kHz they are
               # unstable under that model): accepted here, the benchmark is about timing
               "--param", "stability_margin:=1.5", *options]
        if subprocess.run(cmd, env=os.environ.copy()).returncode != 0:
            print("bench/realtime.py: error: the real-time run failed (see the messages above)", file=sys.stderr)
            return None
        timing = controller_timing(out, 1.0 / rate)
        if timing is None:
            print("bench/realtime.py: error: the bag holds no controller timing", file=sys.stderr)
            return None
        timing["worst_period_s"] = worst_period(out)
        timing["loops"] = bag_loop_statistics(out)
    return timing


def report(label: str, rate: float, timing: dict[str, Any]) -> None:
    faults = ", ".join(f"{node} {v['minor_faults']:.0f}" for node, v in sorted(timing["loops"].items()))
    print(f"{label}: controller ticks {timing['ticks']}, mean period {1e6 * timing['period_mean_s']:.1f} us "
          f"(nominal {1e6 / rate:.1f} us); jitter |period - nominal| p50 {1e6 * timing['jitter_p50_s']:.1f} us, "
          f"p99 {1e6 * timing['jitter_p99_s']:.1f} us, max {1e6 * timing['jitter_max_s']:.1f} us; worst period "
          f"{1e6 * timing['worst_period_s']:.0f} us; missed deadlines {timing['missed_deadlines']} "
          f"({timing['missed_pct']:.3f} %); page faults after warm-up: {faults or 'n/a'}", flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs of each arrangement, alternating (default 3)")
    parser.add_argument("--rate", type=float, default=2000.0, help="control rate in Hz (default 2000)")
    parser.add_argument("--duration-factor", type=float, default=0.5,
                        help="fraction of the 10 s circle to run (default 0.5: 10,000 periods at 2 kHz)")
    parser.add_argument("--baseline", action="store_true",
                        help="the settings before issue 26: normal scheduling, memory not locked, the composed "
                             "process busy-waiting the whole period")
    parser.add_argument("--param", action="append", default=[],
                        help="a node parameter for every run (run_experiment.sh --param), e.g. busy_wait:=0.0001")
    args = parser.parse_args()
    if not 1 <= args.runs <= 100:
        parser.error(f"--runs must be in [1, 100], got {args.runs}")
    common = [opt for p in args.param for opt in ("--param", p)]
    composed = list(COMPOSED)
    if args.baseline:
        common = BASELINE + common
        composed += ["--param", f"busy_wait:={1.0 / args.rate:g}"]
    arrangements = {"four_process": common, "composed": composed + common}
    results: dict[str, list[dict[str, Any]]] = {name: [] for name in arrangements}
    for run in range(args.runs):
        for name, options in arrangements.items():
            timing = measure(args.rate, args.duration_factor, options)
            if timing is None:
                return 1
            report(f"{name} run {run + 1}", args.rate, timing)
            results[name].append(timing)
    four, comp = results["four_process"], results["composed"]
    print("settings: " + ("baseline (before issue 26)" if args.baseline else "defaults") +
          (f", {' '.join(args.param)}" if args.param else ""))
    print(f"four_process_p99_us={max(1e6 * t['jitter_p99_s'] for t in four):.1f} "
          f"four_process_missed_pct={max(t['missed_pct'] for t in four):.3f} "
          f"composed_p99_us={max(1e6 * t['jitter_p99_s'] for t in comp):.1f} "
          f"composed_missed_pct={max(t['missed_pct'] for t in comp):.3f} "
          f"composed_max_us={max(1e6 * t['worst_period_s'] for t in comp):.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
