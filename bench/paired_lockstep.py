"""Benchmark: lockstep steps/s of several source trees, run alternately (paired rounds).

This machine's speed drifts by +-25 % within minutes, so comparing two versions of the code
from separate benchmark runs says little; here the trees take turns, round after round, in a
rotating order, and the per-round ratios to the first tree are reported. Each tree is a
checkout (for example ``git worktree add /tmp/old <commit>``) run with its own sources on
PYTHONPATH and this venv's ROS; ``.`` is this checkout.

Usage: python bench/paired_lockstep.py --tree old=/tmp/old --tree new=. [--rounds 15] [--steps 50000]
       [-- extra run_experiment.sh options; default: --composed --intra-process]
(inside the venv, after make setup)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

ROOT = Path(__file__).resolve().parent.parent


def steps_per_s(tree: Path, steps: int, extra: list[str], env: dict[str, str]) -> float:
    """One run's lockstep rate from the recorder's receive times of /joint_states."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench"
        cmd = ["bash", str(tree / "scripts" / "run_experiment.sh"), "--robot", "serial_3r", "--contour", "circle",
               "--controller", "pdsmc", "--duration-factor", f"{steps / 50000:g}", "--out", str(out),
               "--timeout", "900", *extra]
        subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            conns = [c for c in reader.connections if c.topic == "/joint_states"]
            times = np.array([t for _c, t, _ in reader.messages(connections=conns)])
    return (len(times) - 1) / ((times[-1] - times[0]) * 1e-9)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", action="append", required=True, help="NAME=PATH (the first is the baseline)")
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--steps", type=int, default=50_000)
    parser.add_argument("extra", nargs="*", default=["--composed", "--intra-process"])
    args = parser.parse_args()
    venv = Path(sys.prefix)
    base_env = dict(os.environ, PATH=f"{venv / 'bin'}{os.pathsep}{os.environ['PATH']}",
                    AMENT_PREFIX_PATH=str(venv), NUMBA_CACHE_DIR=str(venv / "numba-cache"))
    trees = []
    for spec in args.tree:
        name, _, path = spec.partition("=")
        tree = (ROOT if path in ("", ".") else Path(path)).resolve()
        trees.append((name, tree, dict(base_env, PYTHONPATH=str(tree))))
    for _name, tree, env in trees:  # warm-up: each tree's numba cache
        steps_per_s(tree, 5000, args.extra, env)
    rates: dict[str, list[float]] = {name: [] for name, _, _ in trees}
    for i in range(args.rounds):
        k = i % len(trees)
        for name, tree, env in trees[k:] + trees[:k]:
            rates[name].append(steps_per_s(tree, args.steps, args.extra, env))
            print(f"round {i + 1}: {name} {rates[name][-1]:,.0f} steps/s", flush=True)
    base_name = trees[0][0]
    base = np.array(rates[base_name])
    for name, values in rates.items():
        v = np.array(values)
        line = f"{name}: median {np.median(v):,.0f}, mean {v.mean():,.0f} steps/s"
        if name != base_name:
            ratio = v / base
            line += (f"; per round against {base_name}: geometric mean {np.exp(np.log(ratio).mean()):.3f}, "
                     f"faster in {int(np.sum(ratio >= 1))} of {len(ratio)}")
        print(line)


if __name__ == "__main__":
    main()
