"""``pdsmc send-goal``."""

from __future__ import annotations

import argparse
import sys

from ..arguments import EXIT_FAILURE, positive_float

EXIT_INTERRUPTED = 130
"""Exit status when Ctrl-C canceled the goal (a shell's for SIGINT)."""


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``send-goal`` on ``pdsmc``'s subcommands."""
    p = sub.add_parser(
        "send-goal", help="send a FollowJointTrajectory goal file to any such action server (ros2 action send_goal): "
        "progress from its feedback, the result; exit 0 only if it succeeded; Ctrl-C cancels the goal")
    p.add_argument("goal", help="the goal file (YAML in the message's layout, e.g. pdsmc excite's goal.yaml)")
    p.add_argument("--action", default="/controller/follow_joint_trajectory",
                   help="the action (default /controller/follow_joint_trajectory)")
    p.add_argument("--server-timeout", type=positive_float, default=10.0,
                   help="seconds to wait for the server and for its answer to the goal (default 10)")
    commands["send-goal"] = run


def run(args: argparse.Namespace) -> int:
    from ..contours.goal_file import read_goal

    data = read_goal(args.goal)  # a bad file: one line, exit 2, before ROS starts
    from ..resources import ensure_ros_environment

    ensure_ros_environment()
    from ..ros.goal_client import goal_message, send_goal

    outcome = send_goal(goal_message(data), args.action, server_timeout=args.server_timeout,
                        progress=lambda line: print(f"pdsmc send-goal: {line}", file=sys.stderr, flush=True))
    print(outcome.describe())
    if outcome.canceled_by_user:
        return EXIT_INTERRUPTED
    return 0 if outcome.succeeded else EXIT_FAILURE
