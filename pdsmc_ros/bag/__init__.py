"""Messages and bags: CDR codecs, step stamps, the MCAP writer's fast path and the run reader.

ROS-free: the nodes and the offline analysis share these (no rclpy import).
"""

from .cdr import (
    decode_float64_multi_array,
    decode_joint_state,
    decode_joint_state_named,
    decode_joint_trajectory,
    decode_joint_trajectory_named,
    decode_joint_trajectory_points,
    decode_stamp,
    decode_string,
    encode_clock,
    encode_float64_multi_array,
    encode_joint_state,
    encode_joint_trajectories,
    encode_joint_trajectory,
    encode_point_stamped,
)
from .mcapscan import scan
from .reader import DESCRIPTION_KEY, RecordedRun, read_run, run_metrics, run_samples
from .stamps import effort_step, header_step, stamp_step, step_stamp
from .writer import MessageAppender, RunProgress, close_chunk, flush_chunk, open_new_bag

__all__ = [
    "DESCRIPTION_KEY",
    "MessageAppender",
    "RecordedRun",
    "RunProgress",
    "close_chunk",
    "decode_float64_multi_array",
    "decode_joint_state",
    "decode_joint_state_named",
    "decode_joint_trajectory",
    "decode_joint_trajectory_named",
    "decode_joint_trajectory_points",
    "decode_stamp",
    "decode_string",
    "effort_step",
    "encode_clock",
    "encode_float64_multi_array",
    "encode_joint_state",
    "encode_joint_trajectories",
    "encode_joint_trajectory",
    "encode_point_stamped",
    "flush_chunk",
    "header_step",
    "open_new_bag",
    "read_run",
    "run_metrics",
    "run_samples",
    "scan",
    "stamp_step",
    "step_stamp",
]
