"""Bench gains of a named URDF arm: its shipped gains slowed, joint by joint, to pass `check-gains --realism bench`
with the arm's viscous friction left out.

Run from the repository (after `make setup`): `.venv/bin/python tools/bench_gains.py ur5 circle pd pdsmc ...`
writes `config/<arm>_bench_<law>.yaml` for each law (a params file of the controller) and prints, per law, the
shipped gains' margin, each joint's bandwidth factor and the margin of the gains written.

Why not `pdsmc tune --realism bench`: it scores the contour error alone, so a joint that barely moves the end
effector along the contour (the UR5's last wrist) is tuned to a stiffness the bench arm's Coulomb friction
defeats (0.1-0.4 rad short of a goal). This keeps the shipped tuning's balance between the joints: it
slows every joint's bandwidth by one factor (a stiffness by its square, a damping by it: BANDWIDTH), the
largest that passes with the margin (x2, real time, the drive's delay and velocity filter modelled), then
gives each joint back, wrists first, as much of its own bandwidth as still passes.

The check it sizes against leaves the arm's viscous friction out, which `check-gains --realism bench` counts
(docs/explanation/stability.md): the bench files are for an arm whose loop cannot be kept free of stalls,
and they do not lean on a friction that an arm has only roughly (the UR10e identification behind the
preset spans 0.044-0.069 s/rad of the effort limits; a joint's viscous friction falls as its grease warms).
Each file's header gives both margins.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

from pdsmc_ros.control.registry import Gains, law
from pdsmc_ros.control.stability import check_gains
from pdsmc_ros.experiments.tuning import Requirement
from pdsmc_ros.runs.builder import make_run

BISECTIONS = 12
"""Halvings of each bandwidth factor's interval (to 1/4096)."""
BANDWIDTH = {"kp": 2.0, "kd": 1.0, "lam": 1.0, "phi": -1.0, "omega_n": 1.0}
"""The power of the bandwidth factor each gain scales with: a stiffness with its square, a damping and the
sliding surface's lambda with it, the boundary layer inversely (the switching term's effective damping is
Ks / phi, docs/explanation/stability.md); Ks is kept (Eq. 3.19 wants it above the disturbance), and so are
zeta and the super-twisting's gains (no linear gains to check)."""
KD_FLOORS = 4
"""Rounds of holding Kd above an Eq. 3.19 bound the slowing broke."""
KD_FLOOR_MARGIN = 1.05
CONFIG = Path(__file__).resolve().parent.parent / "config"


def slowed(gains: Gains, factors: np.ndarray, controller: str, kd_floor: float = 0.0) -> Gains:
    """``gains`` with each joint's bandwidth times ``factors``, every Kd at least ``kd_floor``."""
    values = gains.as_dict()
    scaled = {name: np.asarray(values[name]) * factors ** power for name, power in BANDWIDTH.items() if name in values}
    if "kd" in scaled:
        scaled["kd"] = np.maximum(scaled["kd"], kd_floor)
    # rounded as the params file holds them (4 significant digits), so the check sees what is written
    return gains.replaced({name: [float(f"{x:.4g}") for x in v] for name, v in scaled.items()}, controller)


def _fastest_passing(gains: Gains, controller: str, passes: Callable[[Gains], bool], kd_floor: float) -> np.ndarray:
    """Each joint's bandwidth factor: all joints slowed together by the largest factor that passes (they
    are coupled through the inertia: the elbow's mode moves the shoulder), then each joint given back,
    wrists first (the joints friction holds back most), what still passes."""
    n = gains.n

    def ok(factors: np.ndarray) -> bool:
        return passes(slowed(gains, factors, controller, kd_floor))

    low, high = 0.0, 1.0
    for _ in range(BISECTIONS):
        mid = (low + high) / 2
        low, high = (mid, high) if ok(np.full(n, mid)) else (low, mid)
    if low == 0.0:
        raise SystemExit(f"{controller}: no slowing passes the rate condition")
    factors = np.full(n, low)
    for j in reversed(range(n)):
        low_j, high_j = factors[j], 1.0
        for _ in range(BISECTIONS):
            mid = (low_j + high_j) / 2
            trial = factors.copy()
            trial[j] = mid
            low_j, high_j = (mid, high_j) if ok(trial) else (low_j, mid)
        factors[j] = low_j
    return factors


def bench_gains(arm: str, contour: str, controller: str, rate: float) -> tuple[Gains, np.ndarray, float, float, float]:
    """The gains written, each joint's bandwidth factor, the shipped and the written margins (the arm's viscous
    friction left out), and the written gains' margin with it (``check-gains --realism bench``)."""
    spec = make_run(arm, contour, controller, rate=rate)
    requirement = Requirement(realism="bench")
    delay, filter_hz, viscous = requirement.loop_terms(arm, rate)

    def check(gains: Gains, friction: np.ndarray | None = None):  # noqa: ANN202
        return check_gains(make_run(arm, contour, controller, rate=rate, gains=gains), delay_periods=delay,
                           filter_hz=filter_hz, friction_viscous=friction)

    shipped = check(spec.gains)
    if shipped.passes:
        margin = shipped.rate.margin
        return spec.gains, np.ones(spec.gains.n), margin, margin, check(spec.gains, viscous).rate.margin

    kd_floor = 0.0
    for _ in range(KD_FLOORS):
        factors = _fastest_passing(spec.gains, controller, lambda g: check(g).rate.passes, kd_floor)
        result = check(slowed(spec.gains, factors, controller, kd_floor))
        # a PD-SMC's Eq. 3.19 bounds its Kd from below (lambda M, K + C^T): slowed too far, a joint of
        # little inertia (the last wrist) drops under it; its Kd is held above the bound and the rest redone
        under = [c.rhs for c in result.conditions if not c.holds and c.name.startswith("lambda_m(Kd)")]
        if result.passes or not under:
            break
        kd_floor = KD_FLOOR_MARGIN * max(under)
    if not result.passes:
        raise SystemExit(f"{arm}/{contour}/{controller}: slowed x{np.round(factors, 3).tolist()}: {result.failure()}")
    written = slowed(spec.gains, factors, controller, kd_floor)
    return written, factors, shipped.rate.margin, result.rate.margin, check(written, viscous).rate.margin


def main(arm: str, contour: str, laws: list[str], rate: float = 1000.0) -> int:
    for controller in laws:
        gains, factors, before, after, damped = bench_gains(arm, contour, controller, rate)
        path = CONFIG / f"{arm}_bench_{controller}.yaml"
        values = {k: [float(f"{x:.4g}") for x in v] for k, v in gains.as_dict().items()
                  if k in law(controller).gain_names}
        header = (f"# {controller} gains for {arm} on the MuJoCo stand-in's bench arm (realism:=bench), {rate:g} Hz:\n"
                  f"# the shipped {contour} gains (config/gains.yaml, margin x{before:.2f} there) slowed joint by\n"
                  f"# joint (bandwidth x{', x'.join(f'{f:.3g}' for f in factors)}) until\n"
                  f"# `pdsmc check-gains --robot {arm} --contour {contour} --controller {controller} --rate {rate:g} "
                  f"--realism bench --params-file {path.name}`\n"
                  f"# with the arm's viscous friction left out passes: margin x{after:.2f} (the command, which "
                  f"counts it, gives x{damped:.2f}).\n"
                  f"# Regenerate: .venv/bin/python tools/bench_gains.py {arm} {contour} {controller}\n"
                  f"#   ros2 run pdsmc_ros controller --ros-args --params-file config/{path.name} -p mode:=realtime\n")
        body = {"/**": {"ros__parameters": {"robot": arm, "contour": contour, "type": controller, "rate": rate}},
                "controller": {"ros__parameters": values}}
        path.write_text(header + yaml.safe_dump(body, sort_keys=False, default_flow_style=None))
        print(f"{arm}/{contour}/{controller}: margin x{before:.2f} -> x{after:.2f} (x{damped:.2f} with the viscous "
              f"friction), bandwidth "
              f"{np.round(factors, 3).tolist()}: wrote {path}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) < 4:
        raise SystemExit("usage: tools/bench_gains.py ARM CONTOUR LAW [LAW ...]")
    sys.exit(main(sys.argv[1], sys.argv[2], sys.argv[3:]))
