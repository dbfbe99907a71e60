"""The trajectory generator: its node (node.py) and the references it serializes a window at a
time (reference_windows.py, ROS-free)."""
