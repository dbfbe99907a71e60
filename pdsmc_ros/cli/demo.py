"""``make demo``: the serial circle with PD, SMC and PD-SMC over DDS, compared.

Each controller runs as separate ROS 2 nodes (plant, trajectory, controller,
recorder) in lockstep at 10 kHz through scripts/run_experiment.sh; the bags are
then analysed offline with ``pdsmc analyze`` (Tables 4.25-4.28 of the thesis).
"""

from __future__ import annotations

import argparse
import contextlib
import shlex
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from ..arguments import EXIT_USAGE, OneLineParser, positive_float
from ..experiments.analysis import analyze_bag, comparison_table
from ..resources import ros_environment, script_path, scripts_dir


def command_hint(argv: list[str]) -> str:
    """``argv`` as a user can paste it here: ``pdsmc`` by name when it is on PATH, else by path."""
    exe = scripts_dir() / argv[0]
    found = shutil.which(argv[0])
    if found is None or Path(found).resolve() != exe.resolve():
        with contextlib.suppress(ValueError):
            exe = exe.relative_to(Path.cwd())
        argv = [str(exe), *argv[1:]]
    return " ".join(shlex.quote(a) for a in argv)


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="python -m pdsmc_ros.cli.demo", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None,
                        help="a new directory for the three bags (default: bags/demo-<date>-<time>)")
    parser.add_argument("--duration-factor", type=positive_float, default=1.0,
                        help="scale the contour's 5 s (a short demo: 0.05)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    script = script_path()
    out_dir = args.out or Path("bags") / f"demo-{time.strftime('%Y%m%d-%H%M%S')}"
    if out_dir.exists():
        print(f"demo: error: --out {str(out_dir)!r} already exists; choose a new directory", file=sys.stderr)
        return EXIT_USAGE
    env = ros_environment()
    steps = int(round(50000 * args.duration_factor)) + 1
    print("Serial 3R, circular contour (Tables 4.25-4.28): PD, SMC and PD-SMC as ROS 2 nodes over DDS,")
    print(f"lockstep at 10 kHz ({steps:,} steps each), recorded to MCAP and analysed offline.")
    bags = []
    for controller in ("pd", "smc", "pdsmc"):
        bag = out_dir / controller
        start = time.perf_counter()
        cmd = ["bash", str(script), "--robot", "serial_3r", "--contour", "circle",
               "--controller", controller, "--out", str(bag), "--timeout", "1200",
               "--duration-factor", repr(args.duration_factor)]
        if controller == "smc":
            cmd += ["--smc-reading", "thesis_fit"]
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            sys.stderr.write(proc.stderr)
            print(f"demo: the {controller} run failed; node logs in {bag}.logs/", file=sys.stderr)
            return 1
        print(f"  {controller:6s} recorded {bag} in {time.perf_counter() - start:.0f} s")
        bags.append(bag)
    print()
    print(comparison_table([analyze_bag(b) for b in bags]))
    print()
    print("(SMC with the thesis_fit model reading; see docs/REPRODUCTION.md.)")
    print("Thesis (Table 4.27): contour mean PD 1.133e-4, SMC 1.244e-4, PD-SMC 9.422e-5 m; "
          "PD-SMC 16.8 % smaller than PD, 24.3 % smaller than SMC.")
    print(f"Bags: {out_dir}/  (analyse again with: {command_hint(['pdsmc', 'analyze', str(out_dir)])})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
