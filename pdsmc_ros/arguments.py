"""The command-line parser every front end uses (``pdsmc``, the composed nodes, the demo).

Below the command line: the nodes import it from here, never from :mod:`pdsmc_ros.cli`.
"""

from __future__ import annotations

import argparse
from typing import NoReturn

import numpy as np

EXIT_USAGE = 2
"""Exit status of bad input."""
EXIT_FAILURE = 1
"""Exit status of a failure while running (a diverged run, a failed check)."""


class OneLineParser(argparse.ArgumentParser):
    """argparse with a single-line error message and exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see --help)\n")


def positive_float(text: str) -> float:
    """A positive finite number (``--rate``, ``--duration-factor``, ...)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not np.isfinite(value) or value <= 0.0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def gain_value(text: str) -> tuple[str, list[float]]:
    """``--gain kp=100,200``: a gain's name and values (checked against the law's declaration when the
    run is built: names and bounds are the law's)."""
    name, sep, values = text.partition("=")
    if not sep or not name.strip().isidentifier():
        raise argparse.ArgumentTypeError(f"expected NAME=V1,V2,... (a gain of the law), got {text!r}")
    try:
        numbers = [float(v) for v in values.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"gain {name.strip()}: expected comma-separated numbers, got {values!r}") \
            from None
    if not numbers or not all(np.isfinite(numbers)):
        raise argparse.ArgumentTypeError(f"gain {name.strip()}: expected finite numbers, got {values!r}")
    return name.strip(), numbers
