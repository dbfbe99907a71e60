"""Benchmark: URDF arms (issue 16) -- Pinocchio from Python, the compiled serial chain, lockstep over DDS.

Prints, for the thesis's serial arm from its URDF (3 joints) and the UR5 (6 joints):
- microseconds per Pinocchio ``aba`` call from Python;
- closed-loop steps per second of the plainest Pinocchio loop (RK4 over ``aba``, PD in numpy),
  of the URDF robot as a robot written in numpy (Pinocchio's ``crba``/``nonLinearEffects`` per RK4
  stage, called back from the compiled loop through ``robots.python_form``) and of the compiled loop
  (numba CRBA/RNEA, PD-SMC), measured in the same
  process; the ratio reported is the compiled loop's to the aba loop's;
then the UR5's lockstep steps per second over DDS, composed intra-process (bench/lockstep.py).

Last line: ``urdf_ur5_compiled_steps_per_s=N ratio_to_pinocchio=R ur5_lockstep_steps_per_s=M``.

Usage: python bench/urdf.py [--no-dds]   (inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def aba_us(robot) -> float:  # noqa: ANN001
    """Microseconds per pinocchio.aba call from Python (best of 5 x 20,000)."""
    import pinocchio as pin

    model, data = robot.model, robot.data
    rng = np.random.default_rng(0)
    q, v, tau = rng.uniform(-1, 1, robot.n), rng.uniform(-1, 1, robot.n), rng.uniform(-1, 1, robot.n)
    best = float("inf")
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(20000):
            pin.aba(model, data, q, v, tau)
        best = min(best, (time.perf_counter() - start) / 20000)
    return best * 1e6


def aba_loop_steps_per_s(spec, steps: int = 5000) -> float:  # noqa: ANN001
    """The plainest Pinocchio loop: RK4 over ``pinocchio.aba`` (armature in the model, damping in
    the torque), the PD law in numpy, the reference precomputed (steps per second)."""
    import pinocchio as pin

    from pdsmc_ros.sim.simulator import _reference_samples

    _, refs = _reference_samples(spec)
    robot = spec.robot_model()
    model = robot.model.copy()
    model.armature[:] = robot.J
    data = model.createData()
    kp, kd, b = np.asarray(spec.gains["kp"]), np.asarray(spec.gains["kd"]), robot.B
    h = 1.0 / spec.rate
    q, qd = refs[0, 0].copy(), np.zeros(robot.n)
    steps = min(steps, refs.shape[0] - 1)

    def f(q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> np.ndarray:
        return pin.aba(model, data, q, qd, tau - b * qd)

    start = time.perf_counter()
    for k in range(steps):
        tau = kp * (refs[k, 0] - q) + kd * (refs[k, 1] - qd)
        a1 = f(q, qd, tau)
        a2 = f(q + 0.5 * h * qd, qd + 0.5 * h * a1, tau)
        a3 = f(q + 0.5 * h * (qd + 0.5 * h * a1), qd + 0.5 * h * a2, tau)
        a4 = f(q + h * (qd + 0.5 * h * a2), qd + h * a3, tau)
        q = q + h * qd + h * h / 6.0 * (a1 + a2 + a3)
        qd = qd + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return steps / (time.perf_counter() - start)


def loop_steps_per_s(spec, *, compiled: bool, repeats: int = 3) -> float:  # noqa: ANN001
    """Closed-loop steps per second of ``spec`` (reference sampled beforehand, best of ``repeats``)."""
    from pdsmc_ros.control import ControlLaw
    from pdsmc_ros.sim.loop import closed_loop
    from pdsmc_ros.sim.simulator import _reference_samples

    _, refs = _reference_samples(spec)
    robot = spec.robot_model()
    if not compiled:
        robot = copy.copy(robot)
        robot.kernel = None  # this object only: its numpy methods, behind robots.python_form
    law = ControlLaw.from_spec(spec)  # not compiled: the robot's Pinocchio terms behind robots.python_form
    steps = refs.shape[0] - 1
    every = spec.sample_every
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        closed_loop(robot, law, refs[0, 0], refs, 1.0 / spec.rate, every)
        best = min(best, time.perf_counter() - start)
    return steps / best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-dds", action="store_true", help="skip the lockstep run over DDS")
    args = parser.parse_args()
    from pdsmc_ros.resources import config_dir
    from pdsmc_ros.runs.builder import make_run

    serial = str(config_dir() / "urdf" / "serial_3r.urdf")
    figures = {}
    for label, robot, factor in (("serial_3r.urdf", serial, 0.2), ("ur5", "ur5", 1.0)):
        spec = dataclasses.replace(make_run(robot, "circle", "pdsmc"), duration_factor=factor)
        arm = spec.robot_model()
        aba = aba_us(arm)
        loop_steps_per_s(spec, compiled=True, repeats=1)  # compile
        compiled = loop_steps_per_s(spec, compiled=True)
        numpy_loop = loop_steps_per_s(spec, compiled=False, repeats=1)
        aba_loop = aba_loop_steps_per_s(spec)
        figures[label] = (compiled, compiled / aba_loop)
        print(f"{label} ({arm.n} joints, circle, pdsmc, {spec.rate:g} Hz): pinocchio.aba {aba:.2f} us/call; "
              f"closed loop: Pinocchio RK4 over aba with PD in numpy {aba_loop:,.0f} steps/s, the URDF robot's "
              f"numpy form (Pinocchio terms through robots.python_form) {numpy_loop:,.0f} steps/s, compiled "
              f"{compiled:,.0f} steps/s (x{compiled / aba_loop:.1f} the aba loop, x{compiled / numpy_loop:.0f} "
              "the numpy form)", flush=True)
    lockstep = float("nan")
    if not args.no_dds:
        from lockstep import lockstep_steps_per_s

        lockstep, lost = lockstep_steps_per_s(5000, ["--composed", "--intra-process"], robot="ur5",
                                              circle_steps=5000)
        print(f"ur5 lockstep over DDS, composed intra-process: {lockstep:,.0f} steps/s ({lost} messages lost)")
    compiled, ratio = figures["ur5"]
    print(f"urdf_ur5_compiled_steps_per_s={compiled:.0f} ratio_to_pinocchio={ratio:.1f} "
          f"ur5_lockstep_steps_per_s={lockstep:.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
