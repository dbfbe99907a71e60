"""The plant simulator: its node (node.py) and its own parameters (parameters.py); the ROS-free
plant step, supervision and safe mode are the simulation's (:mod:`pdsmc_ros.sim.supervised`,
:mod:`pdsmc_ros.sim.safe_mode`)."""
