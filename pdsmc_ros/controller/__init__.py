"""The controller: its ROS-free decisions (core.py: inputs, holds, goals, the law's torque; goals.py:
JTC's goal rules, tolerances and the goal state machine; commanding.py: pairing, torque and runaway
guards, staleness; joint_trajectory.py, joints.py, joint_map.py, limits.py, hold.py, warm.py;
gain_check.py: a gain change's stability check, in real time in a process of its own) and its ROS
wiring (node.py: the node; parameters.py: its parameters, output limits and gain updates;
action.py: the FollowJointTrajectory server and ~/controller_state)."""
