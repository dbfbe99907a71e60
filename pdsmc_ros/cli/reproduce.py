"""``pdsmc reproduce``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .options import (
    add_payload_reading,
    worker_count,
)


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``reproduce`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser("reproduce", help="run the thesis matrix and write REPRODUCTION.md")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--workers", type=worker_count, default=None,
                   help="processes (default: cores; with --ros 1, as a composed run takes a core)")
    p.add_argument("--scheduler", default=None, help="run the in-process matrix on a Dask cluster, tcp://HOST:PORT")
    p.add_argument("--smc-reading", default="thesis_fit",
                   help="SMC model estimate for the SMC rows (default: thesis_fit)")
    add_payload_reading(p)
    p.add_argument("--no-readings", action="store_true",
                   help="skip the comparison of SMC readings")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--ros", action="store_true",
                   help="run every case over DDS (lockstep, composed nodes) and analyse the bags")
    p.add_argument("--bags", default="bags/reproduce", help="where --ros records its bags")
    p.add_argument("--only", default=None,
                   help="glob over robot/contour/scenario/controller, e.g. 'serial_3r/circle/*/*'")
    commands["reproduce"] = run


def run(args: argparse.Namespace) -> int:
    from ..experiments.thesis.cells import summarize
    from ..experiments.thesis.report import write_report
    from ..experiments.thesis.reproduce import run_reproduction

    def progress(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    rep = run_reproduction(
        smc=args.smc_reading,
        workers=args.workers,
        readings=not args.no_readings and not args.only,
        progress=None if args.quiet else progress,
        only=args.only,
        ros_bags=Path(args.bags) if args.ros else None,
        payload_reading=args.payload_reading,
        scheduler=args.scheduler,
    )
    paths = write_report(rep, Path(args.out))
    from ..control import law

    main = summarize(c for c in rep.cells if not law(c.controller).model_based)
    smc = summarize(c for c in rep.cells if law(c.controller).model_based)
    print(
        f"{len(rep.results)} runs in {rep.wall_s:.1f} s; PD/PD-SMC cells: median |dev| "
        f"{100 * main['median_abs_dev']:.2f} %, {100 * main['within_5pct']:.1f} % within 5 %; "
        f"SMC cells ({rep.smc_reading}): median |dev| {100 * smc['median_abs_dev']:.2f} %, "
        f"{100 * smc['within_5pct']:.1f} % within 5 %"
    )
    print(f"wrote {paths['markdown']}, {paths['csv']}, {paths['json']}")
    return 0
