"""Several nodes in one process (``composed``, container.py), like a ROS 2 component container."""
