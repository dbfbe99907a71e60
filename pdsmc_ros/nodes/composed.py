"""All four nodes in one process (composed mode), like a ROS 2 component container.

The plant, trajectory, controller and recorder stay separate rclpy nodes with
the same parameters, topics and QoS; they share one process and one executor,
so a lockstep step costs no inter-process hand-off.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from .common import run_nodes
from .controller import ControllerNode
from .plant import PlantNode
from .recorder import RecorderNode
from .trajectory import TrajectoryNode


def main(args: Sequence[str] | None = None) -> int:
    # the recorder first (closed last), the plant last (starts once everyone listens)
    return run_nodes("composed", [RecorderNode, ControllerNode, TrajectoryNode, PlantNode], args)


if __name__ == "__main__":
    sys.exit(main())
