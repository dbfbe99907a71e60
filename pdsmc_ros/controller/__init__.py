"""The controller: its ROS-free decisions (core.py: inputs, holds, goals, the law's torque, their warm-up; goals.py:
JTC's goal rules, tolerances and the goal state machine; commanding.py: pairing, torque and runaway
guards, staleness; joint_trajectory.py, joints.py, limits.py, hold.py), its ROS
wiring (node.py: the node; parameters.py: its run, the gains it is given, its own parameters,
output limits and gain updates; action.py: the FollowJointTrajectory server and
~/controller_state) and, in real time, its sidecar processes (sidecar/: their framing, a child's
life, the goal process's two sides, the gains' stability check)."""
