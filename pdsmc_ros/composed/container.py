"""Several nodes in one process (composed mode), like a ROS 2 component container.

``ros2 run pdsmc_ros composed [--nodes plant,controller] [--intra-process] --ros-args ...``:
the listed nodes (default: all four) stay separate rclpy nodes with the same
parameters, topics and QoS; they share one process and one executor, so a
lockstep step between them costs no inter-process hand-off. With
``--intra-process`` their messages to each other skip DDS as well
(:mod:`pdsmc_ros.ros.intra`, rclcpp's intra-process comms); the figures of
each arrangement are in docs/PERFORMANCE.md. In real time one thread ticks
every composed node, with their real-time settings merged (the highest
``thread_priority``, every core of ``cpu_affinity``, memory locked if any asks:
:mod:`pdsmc_ros.loop.realtime_params`); each node keeps its own loop statistics.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from rclpy.utilities import remove_ros_args

from ..arguments import OneLineParser
from ..controller.node import ControllerNode
from ..loop.lifecycle import EXIT_BAD_INPUT
from ..loop.process import run_nodes
from ..plant.node import PlantNode
from ..recorder.node import RecorderNode
from ..trajectory.node import TrajectoryNode

# creation order: the recorder first (closed last), the plant last (starts once everyone listens)
NODES = {"recorder": RecorderNode, "controller": ControllerNode, "trajectory": TrajectoryNode, "plant": PlantNode}


def parse_nodes(text: str) -> list[str]:
    """The node names of ``--nodes`` (comma-separated), in creation order; ValueError if bad."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in NODES]
    if unknown or not names:
        raise ValueError(f"--nodes takes a comma-separated list of {', '.join(NODES)}; got {text!r}")
    return [n for n in NODES if n in names]


def main(args: Sequence[str] | None = None) -> int:
    argv = list(sys.argv if args is None else args)
    parser = OneLineParser(prog="composed", description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", default=",".join(NODES), help="nodes to run in this process")
    parser.add_argument(
        "--intra-process",
        action="store_true",
        help="hand the loop's messages between these nodes without DDS "
        "(like rclcpp's use_intra_process_comms; peers in other processes still get them over DDS)",
    )
    options = parser.parse_args(remove_ros_args(argv)[1:])
    try:
        names = parse_nodes(options.nodes)
    except ValueError as exc:
        print(f"composed: error: {exc}", file=sys.stderr, flush=True)
        return EXIT_BAD_INPUT
    return run_nodes("composed", [NODES[n] for n in names], argv, intra_process=options.intra_process,
                     node_names=names)


if __name__ == "__main__":
    sys.exit(main())
