"""``pdsmc sweep``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from .options import (
    value_list,
    worker_count,
)


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``sweep`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser("sweep", help="vary one gain of a law (the PD-SMC's: Section 4.2.3, Table 4.15)")
    p.add_argument("--param", required=True,
                   help="the gain varied: for the PD-SMC one Table 4.15 gives a range (kp, kd, ks, lam: the "
                   "thesis's lambda), for another law any gain it declares (with --values)")
    p.add_argument("--controller", default="pdsmc",
                   help="the law swept (default pdsmc, the thesis's sweep); the others keep its presets")
    p.add_argument("--robot", required=True, help="a registered robot: serial_3r, parallel_5r, ...")
    p.add_argument("--contour", required=True)
    p.add_argument("--out", default=None, help="write sweep_<param>.csv and .png here")
    p.add_argument("--workers", type=worker_count, default=None)
    p.add_argument("--scheduler", default=None, help="run the sweep on a Dask cluster, tcp://HOST:PORT")
    p.add_argument("--values", type=value_list, default=None,
                   help="comma-separated values instead of the thesis's (e.g. 1,10,100)")
    commands["sweep"] = run


def run(args: argparse.Namespace) -> int:
    from ..experiments.sweep import run_sweep

    def progress(done: int, total: int, _res: object) -> None:
        print(f"[{done}/{total}]", end="\r", file=sys.stderr, flush=True)

    from ..control import law_label

    param, points = run_sweep(args.param, args.robot, args.contour, values=args.values, workers=args.workers,
                              progress=progress, scheduler=args.scheduler, controller=args.controller)
    label = param
    name = law_label(args.controller)
    others = ("others at Kp=5000, Kd=1000, Ks=5, lambda=10, phi=0.5 (Section 4.2.3)" if args.controller == "pdsmc"
              else "the others at the law's presets")
    print(f"{name}, {args.robot} / {args.contour}: {label} varied, {others}")
    print(f"{label:>8s} {'rate (Hz)':>10s} {'mean (m)':>11s} {'S.D. (m)':>11s} {'max (m)':>11s} {'within':>8s}")
    for p in points:
        flag = "  diverged" if p.diverged else ""
        print(f"{p.value:8g} {p.rate:10g} {p.contour_mean:11.4e} {p.contour_sd:11.4e} {p.contour_max:11.4e} "
              f"{p.within_pct:7.2f}%{flag}")
    if args.out:
        import csv

        from ..experiments.plots import plot_sweep

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        with (out / f"sweep_{label}.csv").open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow([label, "rate_hz", "contour_mean", "contour_sd", "contour_max", "within_pct", "diverged"])
            for p in points:
                writer.writerow(
                    [p.value, p.rate, p.contour_mean, p.contour_sd, p.contour_max, p.within_pct, p.diverged]
                )
        ok = [p for p in points if not p.diverged]
        plot_sweep(label, np.array([p.value for p in ok]), np.array([p.contour_mean for p in ok]),
                   np.array([p.contour_sd for p in ok]), np.array([p.contour_max for p in ok]),
                   out / f"sweep_{label}.png", f"{name} {args.robot}/{args.contour}: {label}")
        print(f"wrote {out}/sweep_{label}.csv and .png", file=sys.stderr)
    return 0
