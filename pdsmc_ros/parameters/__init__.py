"""Settings declared once, as data (:mod:`.declaration`, :mod:`.run_table`, :mod:`.tables`; ROS-free).

From each node's table derive the rclpy declarations and descriptors and the on-set guard
(:mod:`.ros`, the only module here that imports rclpy), the params-file checks of every entry
point (:mod:`pdsmc_ros.parameters.params_file`) and the documentation's parameter reference (:func:`catalog`).
"""

from .declaration import TYPES, ParameterSpec, check_values
from .run_table import RUN, RUN_DEFAULTS

TABLES = ("BUSY_WAIT", "CONTROLLER", "NODES", "OUTPUT_LIMITS", "PLANT", "RECORDER", "SAFETY", "STABILITY",
    "TRAJECTORY", "VIEWER", "catalog", "gain_parameters", "mujoco_driver_parameters", "node_parameters",
    "package_parameter_names", "parameter_names", "realtime_parameters", "run_parameters")
"""The names :mod:`.tables` gives, imported from there when first asked (the tables read the law and
robot registries, which load numba; the command line needs only :mod:`.run_table`)."""


def __getattr__(name: str) -> object:
    if name in TABLES:
        from . import tables

        return getattr(tables, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")



__all__ = [
    "RUN",
    "RUN_DEFAULTS",
    "BUSY_WAIT",
    "CONTROLLER",
    "NODES",
    "OUTPUT_LIMITS",
    "PLANT",
    "RECORDER",
    "SAFETY",
    "STABILITY",
    "TRAJECTORY",
    "TYPES",
    "VIEWER",
    "ParameterSpec",
    "catalog",
    "check_values",
    "gain_parameters",
    "mujoco_driver_parameters",
    "node_parameters",
    "package_parameter_names",
    "parameter_names",
    "realtime_parameters",
    "run_parameters",
]
