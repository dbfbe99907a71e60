"""pdsmc_ros: PD, SMC and hybrid PD-SMC control of robotic manipulators on ROS 2.

The maths (``robots``, ``contours``, ``control``, ``metrics``, ``sim``), the settings
(``parameters``) and the run (``runs``) are ROS-free numpy code; each ROS component is a folder
holding its ROS-free decisions beside its thin rclpy wiring (``controller``, ``plant``,
``trajectory``, ``recorder``, ``mujoco_driver``, ``viewer``), on the shared ``loop`` and ``ros``
plumbing; the modules directly under this package are the foundation every layer uses. The layers
and their rules: docs/explanation/architecture.md, test/test_dependencies.py.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

__version__ = "0.1.0"


def _venv_kernel_cache() -> None:
    """numba's kernel cache in the venv (``<prefix>/numba-cache``, which ``make setup`` fills:
    :mod:`pdsmc_ros.kernels.precompile`) unless ``NUMBA_CACHE_DIR`` names another.

    Without it a command run as ``.venv/bin/pdsmc`` or from a script, with no ``make`` around it,
    compiled every kernel again into the installed package's ``__pycache__`` instead of loading
    what ``make setup`` compiled. Set before any kernel is defined
    (numba picks a function's cache directory when it is decorated); the nodes a command starts
    inherit it. Outside a venv, or where the venv cannot be written, numba's own default stays.
    """
    prefix = Path(sys.prefix)
    if os.environ.get("NUMBA_CACHE_DIR") or sys.prefix == sys.base_prefix or not os.access(prefix, os.W_OK):
        return
    cache = str(prefix / "numba-cache")
    os.environ["NUMBA_CACHE_DIR"] = cache
    config = sys.modules.get("numba.core.config")
    if config is not None:  # numba was imported first and has read the environment already
        config.CACHE_DIR = cache  # type: ignore[attr-defined]


_venv_kernel_cache()
