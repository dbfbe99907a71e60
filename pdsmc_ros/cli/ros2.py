"""A minimal ``ros2`` command for the PyPI ROS wheels, which ship none.

Only ``ros2 run <package> <executable> [args...]`` is implemented, the way
ros2run does it: the package prefix comes from the ament index and the
executable from ``<prefix>/lib/<package>/``. Where a full ROS 2 install
(``ros2cli``) is importable, every verb is handed to it instead.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

USAGE = "usage: ros2 run <package> <executable> [argv ...]"


def _real_ros2(argv: Sequence[str]) -> int | None:
    try:
        from ros2cli.cli import main as ros2cli_main  # type: ignore[import-not-found]
    except ImportError:
        return None
    sys.argv = ["ros2", *argv]
    return int(ros2cli_main() or 0)


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    delegated = _real_ros2(argv)
    if delegated is not None:
        return delegated
    if not argv or argv[0] in ("-h", "--help"):
        print(USAGE)
        print("This minimal ros2 (pdsmc_ros) implements only `run`; other verbs need a full ROS 2 install.")
        return 0 if argv else 2
    verb = argv[0]
    if verb != "run":
        print(f"ros2: '{verb}' is not available here: this minimal ros2 (pdsmc_ros, PyPI ROS wheels) "
              "implements only `run`; install a full ROS 2 distribution for other verbs", file=sys.stderr)
        return 2
    if len(argv) < 3:
        print(f"ros2 run: error: package and executable are required ({USAGE})", file=sys.stderr)
        return 2
    package, executable, rest = argv[1], argv[2], argv[3:]
    from ..resources import ensure_ros_environment

    ensure_ros_environment()
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    try:
        prefix = get_package_prefix(package)
    except PackageNotFoundError:
        print(f"ros2 run: error: package '{package}' not found in AMENT_PREFIX_PATH "
              f"({os.environ.get('AMENT_PREFIX_PATH', '')})", file=sys.stderr)
        return 2
    libdir = os.path.join(prefix, "lib", package)
    path = os.path.join(libdir, executable)
    if not (os.path.isfile(path) and os.access(path, os.X_OK)):
        available = sorted(os.listdir(libdir)) if os.path.isdir(libdir) else []
        print(f"ros2 run: error: no executable '{executable}' in package '{package}' "
              f"(available: {', '.join(available) or 'none'})", file=sys.stderr)
        return 2
    sys.stdout.flush()
    os.execv(path, [path, *rest])
    return 0  # not reached


if __name__ == "__main__":
    sys.exit(main())
