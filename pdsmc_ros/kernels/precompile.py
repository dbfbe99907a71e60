"""Compile the package's numba kernels into numba's on-disk cache, once, at install time.

numba compiles a kernel on its first call in a process and keeps it in its cache
(``NUMBA_CACHE_DIR``; the venv's ``numba-cache``). With an empty cache the first
command after an install compiles for tens of seconds per robot kind before it computes
anything, and the nodes a launch starts together each compile the same kernels at once
(figures: docs/PERFORMANCE.md).
``make setup`` runs ``python -m pdsmc_ros.kernels.precompile`` after installing: every compiled
robot kind (the thesis's serial arm, the five-bar, a URDF chain) runs a short closed
loop (every law's branch is in it), its plant step, every law's torque as the
controller node computes it, and the run statistics, so later commands load them.

numba keys its cache by a kernel's source file path: a clone with the package installed
from it has two copies, each compiled by its own run (``make setup`` runs both at once).
Nothing is kept but the cache; a kernel this does not reach still compiles on first use.
ROS-free.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..arguments import EXIT_USAGE, OneLineParser
from ..control.law import ControlLaw
from ..control.registry import law_names
from ..errors import ConfigError
from ..robots.catalog import resolve_robot
from ..runs.builder import make_run
from ..sim.plant import PlantStepper
from ..sim.simulator import simulate

# one robot of each compiled kind: the kernels are compiled per kind, not per arm
ROBOTS = ("serial_3r", "parallel_5r", "ur5")
DURATION_FACTOR = 0.05  # a twentieth of the contour: every kernel is called, little is computed


def precompile(robots: Sequence[str] = ROBOTS) -> None:
    """Call every kernel ``robots``' runs, plants and laws use once (numba caches them)."""
    for robot in robots:
        # an arm without preset gains runs the law's neutral ones: compiling needs no good run
        spec = dataclasses.replace(make_run(robot, "circle", "pdsmc", needs_gains=False),
                                   duration_factor=DURATION_FACTOR)
        simulate(spec, check_stability=False)
        simulate(spec, check_stability=False, keep_samples=False)
        model = spec.robot_model()
        rest = np.zeros(model.n)
        PlantStepper(model, 1.0 / spec.rate, rest, rest).warm_up()
        # the model's own methods, which analysis, the nodes' checks and users' scripts call
        home = model.home_configuration()
        q = rest if home is None else home
        model.forward_kinematics(q)
        model.jacobian(q)
        model.coriolis_matrix(q, rest)
        model.inverse_dynamics(q, rest, rest)
        model.total_energy(q, rest)
        for name in law_names():
            ControlLaw.from_spec(make_run(robot, "circle", name, needs_gains=False)).warm_up(rest, rest)


def main(args: Sequence[str] | None = None) -> int:
    parser = OneLineParser(prog="precompile", description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default=",".join(ROBOTS),
                        help=f"comma-separated robots whose kernels to compile (default: {','.join(ROBOTS)})")
    options = parser.parse_args(args)
    robots = [r.strip() for r in options.robots.split(",") if r.strip()]
    if not robots:
        parser.error(f"--robots takes a comma-separated list of robots, got {options.robots!r}")
    start = time.perf_counter()
    try:
        for robot in robots:
            resolve_robot(robot)
        precompile(robots)
    except ConfigError as exc:
        print(f"precompile: error: {exc}", file=sys.stderr, flush=True)
        return EXIT_USAGE
    print(f"precompile: the kernels of {', '.join(robots)} and every law compiled in "
          f"{time.perf_counter() - start:.0f} s ({Path(__file__).resolve().parent})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
