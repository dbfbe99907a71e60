"""Benchmark: the law against the MuJoCo stand-in in lockstep (``--plant mujoco``) against a bare
``mj_step`` loop of the same model, measured in the same run (issue 50).

For each arm (the serial 3R at 10 kHz, the five-bar at 5 kHz, the UR5 at 1 kHz; circle, PD-SMC)
and each preset (``ideal``, ``bench``) it times, on the same compiled MuJoCo model:

- ``bare``: ``for _ in range(N): mujoco.mj_step(m, d)`` in Python from the run's start, no torque
  (what a user writes to step MuJoCo);
- ``floor``: MuJoCo's own cost on the run's motion: ``mj_step`` called from compiled code with the
  run's torques replayed, one a step;
- ``lockstep``: one run's closed loop (:class:`pdsmc_ros.sim.mujoco_lockstep.MujocoLoop`: the drive,
  the law, the soft limits, the statistics' samples and MuJoCo's step each period), its call only;
- ``simulate``: the whole ``simulate(spec, stand_in=...)`` (model build, reference, statistics).

It prints microseconds a step (the best of ``--repeats``) and the ratios lockstep / bare and
lockstep / floor. Target: lockstep <= 2x bare.

Last line: ``<arm>_<preset>_ratio=X ...`` (lockstep / bare).

Usage: python bench/mujoco_lockstep.py [--repeats 5]   (inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np
from numba import njit

from pdsmc_ros.control import ControlLaw
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate
from pdsmc_ros.sim.drive import mj_step_function
from pdsmc_ros.sim.mujoco_lockstep import StandIn
from pdsmc_ros.sim.simulator import _reference_samples

RUNS = (("serial_3r", "circle"), ("parallel_5r", "circle"), ("ur5", "circle"))


@njit(cache=True)
def _floor(step, model, data, ctrl, torques):  # noqa: ANN001, ANN202
    for k in range(torques.shape[0]):
        for i in range(ctrl.shape[0]):
            ctrl[i] = torques[k, i]
        step(model, data)


def bare_python(m: mujoco.MjModel, d: mujoco.MjData, steps: int) -> float:
    step = mujoco.mj_step
    start = time.perf_counter()
    for _ in range(steps):
        step(m, d)
    return time.perf_counter() - start


def measure(robot: str, contour: str, preset: str, repeats: int) -> dict[str, float]:
    spec = make_run(robot, contour, "pdsmc")
    _, refs = _reference_samples(spec)
    steps = refs.shape[0]
    stand_in = StandIn(preset)
    plant = spec.robot_model()
    best = {"bare": np.inf, "floor": np.inf, "lockstep": np.inf, "simulate": np.inf}
    for _ in range(repeats):
        loop = stand_in.loop(spec.robot, spec.rate, plant)
        law = ControlLaw.from_spec(spec)
        start = time.perf_counter()
        outcome = loop(plant, law, refs[0, 0], refs, 1.0 / spec.rate, spec.sample_every, every_step=True)[3]
        best["lockstep"] = min(best["lockstep"], (time.perf_counter() - start) / steps)
        # the same model, from the run's start
        m, d = loop.arm.model, loop.arm.data()
        loop.data = d
        loop.start(refs[0, 0], None)
        best["bare"] = min(best["bare"], bare_python(m, d, steps) / steps)
        loop.start(refs[0, 0], None)
        start = time.perf_counter()
        _floor(mj_step_function(), m._address, d._address, d.ctrl, np.ascontiguousarray(outcome.step_tau))
        best["floor"] = min(best["floor"], (time.perf_counter() - start) / steps)
        start = time.perf_counter()
        simulate(spec, check_stability=False, stand_in=stand_in)
        best["simulate"] = min(best["simulate"], (time.perf_counter() - start) / steps)
    best["steps"] = steps
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    for robot, contour in RUNS:  # compile and load everything once
        measure(robot, contour, "bench", 1)
    ratios = []
    print(f"{'arm':12s} {'preset':6s} {'steps':>7s} {'bare us':>8s} {'floor us':>9s} {'lockstep us':>12s} "
          f"{'simulate us':>12s} {'lock/bare':>10s} {'lock/floor':>11s}")
    for robot, contour in RUNS:
        for preset in ("ideal", "bench"):
            r = measure(robot, contour, preset, args.repeats)
            ratio = r["lockstep"] / r["bare"]
            ratios.append(f"{robot}_{preset}_ratio={ratio:.2f}")
            print(f"{robot:12s} {preset:6s} {int(r['steps']):7d} {r['bare'] * 1e6:8.2f} {r['floor'] * 1e6:9.2f} "
                  f"{r['lockstep'] * 1e6:12.2f} {r['simulate'] * 1e6:12.2f} {ratio:10.2f} "
                  f"{r['lockstep'] / r['floor']:11.2f}")
    print(" ".join(ratios))


if __name__ == "__main__":
    main()
