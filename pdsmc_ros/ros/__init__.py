"""ROS plumbing the nodes share: topic names and QoS (topics.py), guarded publishers (publishers.py),
``/diagnostics`` (diagnostics.py) and the arm on ``/robot_description`` (robot_description.py)."""
