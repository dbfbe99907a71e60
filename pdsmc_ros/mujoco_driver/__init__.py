"""The MuJoCo stand-in for a robot: its node (node.py); the ROS-free driver is
:mod:`pdsmc_ros.mujoco_driver.driver`."""
