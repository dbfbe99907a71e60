"""The command-line parser every front end uses (``pdsmc``, the composed nodes, the demo).

Below the command line: the nodes import it from here, never from :mod:`pdsmc_ros.cli`.
"""

from __future__ import annotations

import argparse
from typing import NoReturn

EXIT_USAGE = 2
"""Exit status of bad input."""


class OneLineParser(argparse.ArgumentParser):
    """argparse with a single-line error message and exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see --help)\n")
