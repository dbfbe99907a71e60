"""pdsmc_ros: PD, SMC and hybrid PD-SMC control of robotic manipulators on ROS 2.

The modules directly under this package are ROS-free numpy code (models,
trajectories, controllers, simulator, metrics); ``pdsmc_ros.nodes`` holds the
thin rclpy wrappers.
"""

from __future__ import annotations

__version__ = "0.1.0"
