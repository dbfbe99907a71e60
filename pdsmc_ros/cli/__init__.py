"""The ``pdsmc`` command: simulate, reproduce the thesis, check gains, tune, sweep, Monte Carlo,
compare laws, re-test the thesis's claims on the stand-in (ladder), analyse bags, excite and
identify an arm, send a goal, check the machine for real time.
One module per subcommand (``add_parser`` registers it, ``run`` runs it).

Every error is one line on stderr naming the input and what is allowed, with
exit status 2 for bad input and 1 for a failure while running.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from .. import __version__
from ..arguments import EXIT_FAILURE, EXIT_USAGE, OneLineParser
from ..errors import InvalidInputError, PdsmcError
from ..loop import rt_check
from . import (
    analyze,
    check_gains,
    compare,
    excite,
    identify,
    ladder,
    montecarlo,
    reproduce,
    send_goal,
    simulate,
    sweep,
    tune,
)
from .options import spec_from_args

SUBCOMMANDS = (simulate, reproduce, analyze, sweep, check_gains, montecarlo, compare, ladder, tune, excite, send_goal,
               identify, rt_check)
"""The modules of the subcommands, in ``--help``'s order."""

__all__ = ["EXIT_FAILURE", "EXIT_USAGE", "analyze_main", "build_parser", "main", "spec_from_args"]


def build_parser(commands: dict[str, Callable[[argparse.Namespace], int]] | None = None) -> argparse.ArgumentParser:
    """The ``pdsmc`` parser; ``commands`` (if given) receives each subcommand's ``run``."""
    parser = OneLineParser(prog="pdsmc", description=__doc__)
    parser.add_argument("--version", action="version", version=f"pdsmc_ros {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    for module in SUBCOMMANDS:
        module.add_parser(sub, {} if commands is None else commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    commands: dict[str, Callable[[argparse.Namespace], int]] = {}
    parser = build_parser(commands)
    args = parser.parse_args(argv)
    try:
        return commands[args.command](args)
    except InvalidInputError as exc:
        print(f"pdsmc {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except PdsmcError as exc:
        print(f"pdsmc {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_FAILURE
    except KeyboardInterrupt:
        print(f"pdsmc {args.command}: interrupted", file=sys.stderr)
        return 130


def analyze_main(argv: Sequence[str] | None = None) -> int:
    """``ros2 run pdsmc_ros analyze BAG ...``: the same as ``pdsmc analyze``."""
    return main(["analyze", *(sys.argv[1:] if argv is None else argv)])
