"""Where the package finds its own files, and the environment its ROS commands need.

The presets (``config/``) and the orchestration script (``scripts/``) live at the
top of the source tree, and an install carries a copy of both inside the package
(``pdsmc_ros/data/config``, ``pdsmc_ros/data/scripts``: package data, see
setup.py), so the ROS-free core finds them with :mod:`importlib.resources`
whatever the environment and the working directory. The same files are also
installed under ``share/pdsmc_ros`` for ROS tools (the ament index), which this
module never needs.
"""

from __future__ import annotations

import os
import sys
import sysconfig
from collections.abc import Mapping
from importlib import resources
from pathlib import Path

from .errors import ConfigError

PACKAGE = "pdsmc_ros"
_MARKER = Path("config") / "gains.yaml"


def data_root() -> Path:
    """The directory holding ``config/`` and ``scripts/``.

    An installed package's own ``data/`` directory; in a source checkout (the
    package imported from the tree, as the tests do), the checkout's top level.

    Raises
    ------
    ConfigError
        If neither holds the presets (a broken install).
    """
    installed = Path(str(resources.files(PACKAGE))) / "data"
    checkout = Path(__file__).resolve().parent.parent
    for root in (installed, checkout):
        if (root / _MARKER).is_file() and (root is installed or (root / "package.xml").is_file()):
            return root
    raise ConfigError(
        f"cannot find the pdsmc_ros presets: no {installed / _MARKER} (package data) and no source "
        f"checkout at {checkout}; reinstall the package (make setup)"
    )


def config_dir() -> Path:
    """Directory holding the YAML presets (``config/``)."""
    return data_root() / "config"


def script_path(name: str = "run_experiment.sh") -> Path:
    """Path of one of the package's shell scripts (``scripts/``)."""
    return data_root() / "scripts" / name


def scripts_dir() -> Path:
    """Where this Python environment's console scripts (``pdsmc``, ``ros2``, the nodes) are."""
    return Path(sysconfig.get_path("scripts"))


def ros_environment(base: Mapping[str, str] | None = None) -> dict[str, str]:
    """``base`` (default: this process's environment) as the ROS entry points need it.

    The PyPI ROS wheels set no ``AMENT_PREFIX_PATH``, and a user may run
    ``.venv/bin/ros2`` or a node executable with a clean environment: this
    environment's prefix is put first in ``AMENT_PREFIX_PATH`` unless it is
    already there (other prefixes, such as a sourced ROS install, are kept), and
    its scripts directory likewise in ``PATH``, so ``ros2 run pdsmc_ros ...`` and the
    orchestration script find the package and its executables.
    """
    env = dict(os.environ if base is None else base)
    env["AMENT_PREFIX_PATH"] = _prepend(sys.prefix, env.get("AMENT_PREFIX_PATH", ""))
    env["PATH"] = _prepend(str(scripts_dir()), env.get("PATH", ""))
    return env


def ensure_ros_environment() -> None:
    """Apply :func:`ros_environment` to this process (before any ament index lookup)."""
    env = ros_environment()
    for key in ("AMENT_PREFIX_PATH", "PATH"):
        os.environ[key] = env[key]


def _prepend(entry: str, value: str) -> str:
    parts = [p for p in value.split(os.pathsep) if p]
    if entry in parts:
        return value
    return os.pathsep.join([entry, *parts])
