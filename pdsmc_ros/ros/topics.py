"""Topic names and QoS of the pdsmc_ros nodes (ros2_control conventions where they exist)."""

from __future__ import annotations

from rclpy.clock import Clock, ClockType
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# --------------------------------------------------------------------------- #
# Topics (ros2_control conventions where they exist)
# --------------------------------------------------------------------------- #
TOPIC_JOINT_STATES = "joint_states"
# every state of the loop, throttled to THROTTLE_RATE per second of sim time (topic_tools' name):
# what an observer such as the live viewer takes, so the loop's own topic has no extra reader
TOPIC_JOINT_STATES_THROTTLED = "joint_states_throttle"
THROTTLE_RATE = 100.0
TOPIC_EFFORT = "effort_controller/commands"
TOPIC_REFERENCE = "reference"
TOPIC_EE_DESIRED = "end_effector/desired"
TOPIC_EE_ACTUAL = "end_effector/actual"
TOPIC_DESCRIPTION = "pdsmc/run_description"
TOPIC_TIMING = "pdsmc/controller_timing"
TOPIC_DIAGNOSTICS = "diagnostics"
TOPIC_JOINT_TRAJECTORY = "~/joint_trajectory"  # joint_trajectory_controller's topic interface
TOPIC_ROBOT_DESCRIPTION = "robot_description"

MODES = ("lockstep", "realtime")


def _qos(depth: int | None, *, best_effort: bool = False, latched: bool = False) -> QoSProfile:
    """Reliable and volatile unless said; every sample when ``depth`` is None, else the newest ``depth``."""
    if depth is None:
        profile = QoSProfile(history=HistoryPolicy.KEEP_ALL)
    else:
        profile = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth)
    profile.reliability = ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE
    profile.durability = DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE
    return profile


# Subscriptions of the lockstep loop and the recorder: every sample, in order (reliable,
# keep-all; a shallow keep-last queue lost data).
LOCKSTEP_QOS = _qos(None)
# Publishers of the loop: reliable with a deep but bounded history. A keep-all writer
# blocks in publish() once a subscriber stops acknowledging (a killed node, until DDS
# drops it, or a new node still starting): that froze the plant in safe mode. A live
# subscriber acknowledges each sample long before 10,000 newer ones are written.
STREAM_DEPTH = 10_000
STREAM_QOS = _qos(STREAM_DEPTH)
# Real time: a controller acts on the newest sample; a queue of old ones is only delay.
LATEST_QOS = _qos(1)
# Observers (the live viewer): best effort, newest few; a reliable writer never waits for
# them, and the plant and the trajectory do not count them among the subscribers they wait for.
OBSERVER_QOS = _qos(10, best_effort=True)
# The run description is published once and must reach late joiners.
LATCHED_QOS = _qos(1, latched=True)
# Standard trajectories (joint_trajectory_controller subscribes with the system default QoS:
# reliable, volatile, keep last 10)
TRAJECTORY_QOS = _qos(10)

# Start-up polling must not wait for /clock, which starts only once everyone is there.
STEADY_CLOCK = Clock(clock_type=ClockType.STEADY_TIME)
