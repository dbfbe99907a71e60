"""ROS-free run-time decisions of the nodes (real-time settings, loop statistics, hold, goal execution)."""
