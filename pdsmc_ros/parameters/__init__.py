"""Node parameters declared once, as data (:mod:`.declaration`, :mod:`.tables`; ROS-free).

From each node's table derive the rclpy declarations and descriptors and the on-set guard
(:mod:`.ros`, the only module here that imports rclpy), the params-file checks of every entry
point (:mod:`pdsmc_ros.parameters.params_file`) and the documentation's parameter reference (:func:`catalog`).
"""

from .declaration import TYPES, ParameterSpec, check_values
from .tables import (
    BUSY_WAIT,
    CONTROLLER,
    NODES,
    OUTPUT_LIMITS,
    PLANT,
    RECORDER,
    SAFETY,
    STABILITY,
    TRAJECTORY,
    VIEWER,
    catalog,
    gain_parameters,
    mujoco_driver_parameters,
    node_parameters,
    package_parameter_names,
    parameter_names,
    realtime_parameters,
    run_parameters,
)

__all__ = [
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
