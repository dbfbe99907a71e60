"""Gains of the named URDF arms in config/gains.yaml: `pdsmc tune` for each contour group and law.

Run from the repository (after `make setup`): `.venv/bin/python tools/tune_arms.py ur5 panda [linear circle
ellipse]` (the gain groups, all by default). Prints
the YAML block of each arm for config/gains.yaml (and, as each law is done, its gains as a one-line YAML
comment, so that a long run interrupted keeps what it found) and, on stderr, the contour error before and
after and the margin of the gains kept (rate / lowest stable rate in real time, with the loop's delay of
stability.REALTIME_DELAY_PERIODS; tune keeps only gains that `pdsmc check-gains` accepts there, margin x2,
and the PD-SMC's Eq. 3.19 conditions) with the longest constant delay they stay stable with.
"""

from __future__ import annotations

import sys

import yaml

from pdsmc_ros.control.registry import Gains
from pdsmc_ros.control.stability import check_gains, tolerated_delay
from pdsmc_ros.experiments.tuning import tune
from pdsmc_ros.runs.builder import make_run

# each gain group's contours: tuned on the first, every candidate checked on all of them
GROUPS = {"linear": ("zigzag", "diamond"), "circle": ("circle",), "ellipse": ("ellipse",)}
LAWS = ("pd", "smc", "pdsmc")


def main(arms: list[str], groups: list[str]) -> int:
    for arm in arms:
        block: dict[str, dict[str, dict[str, list[float]]]] = {}
        for group in groups:
            contour, *also = GROUPS[group]
            for controller in LAWS:
                result = tune(arm, contour, controller, also=also)
                gains = result.best.gains.as_dict()
                block.setdefault(group, {})[controller] = {
                    k: [float(f"{x:.4g}") for x in gains[k]] for k in _needed(controller)}
                # the gains as config/gains.yaml holds them, on every contour of the group
                shipped = Gains.from_mapping(block[group][controller], result.spec.gains.n, controller)
                checks = [check_gains(make_run(arm, name, controller, gains=shipped)) for name in GROUPS[group]]
                print(f"{arm}/{contour}/{controller}: contour mean {result.start.contour_mean:.4e} -> "
                      f"{result.best.contour_mean:.4e} m ({len(result.tried)} runs), max torque "
                      f"{max(result.best.max_torque):.4g} N m, real-time margin "
                      + ", ".join(f"x{c.rate.margin:.2f}" for c in checks)
                      + f" ({'passes' if all(c.passes for c in checks) else 'FAILS'} check-gains), stable with a "
                      f"constant delay up to {tolerated_delay(result.spec, result.spec.reference())} periods",
                      file=sys.stderr, flush=True)
                one = yaml.safe_dump({arm: {group: {controller: block[group][controller]}}}, default_flow_style=True,
                                     width=100000).strip()
                print(f"# {one}", flush=True)
        print(yaml.safe_dump({arm: block}, sort_keys=False, default_flow_style=None, width=120))
    return 0


def _needed(controller: str) -> tuple[str, ...]:
    from pdsmc_ros.control import law

    return law(controller).gain_names


if __name__ == "__main__":
    names = sys.argv[1:] or ["ur5", "panda"]
    sys.exit(main([n for n in names if n not in GROUPS], [n for n in names if n in GROUPS] or list(GROUPS)))
