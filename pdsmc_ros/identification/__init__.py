"""Identification of an arm's dynamics from its own runs (ROS-free)."""
