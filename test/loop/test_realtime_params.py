"""The spin before a tick that apply_settings chooses at SCHED_FIFO (pdsmc_ros/loop/realtime_params.py):
a thread ticking one loop node spins FIFO_BUSY_WAIT_S, a composed thread ticking several spins
FIFO_COMPOSED_BUSY_WAIT_S (never more than FIFO_BUSY_SHARE of the period), a value given is kept --
also the value that is the automatic choice at normal priority."""

from __future__ import annotations

import os
from types import SimpleNamespace

import pytest

pytest.importorskip("rclpy")

from pdsmc_ros.loop.realtime import (
    BUSY_WAIT_S,
    FIFO_BUSY_SHARE,
    FIFO_BUSY_WAIT_S,
    FIFO_COMPOSED_BUSY_WAIT_S,
    RealtimeSettings,
    policy_of,
    restore,
)
from pdsmc_ros.loop.realtime_params import apply_settings  # noqa: E402
from pdsmc_ros.parameters.tables import AUTO_BUSY_WAIT


class Logger:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def info(self, text: str) -> None:
        self.lines.append(text)

    warn = info


def spin(loops: int, period: float, busy_wait: float = AUTO_BUSY_WAIT) -> tuple[float, bool, list[str]]:
    """The busy-wait apply_settings returns for ``loops`` loop nodes at FIFO 1, whether FIFO held."""
    logger = Logger()
    node = SimpleNamespace(get_logger=lambda: logger)
    reports = [SimpleNamespace(settings=RealtimeSettings(thread_priority=1), stats=object()) for _ in range(loops)]
    reports.append(SimpleNamespace(settings=RealtimeSettings(), stats=None))  # an observer: not a loop
    applied, chosen = apply_settings(reports, node, period, busy_wait)  # type: ignore[arg-type]
    try:
        return chosen, policy_of(0) == os.SCHED_FIFO, logger.lines
    finally:
        restore(applied)


def test_one_loop_spins_briefly_a_composed_loop_longer_and_a_given_value_is_kept() -> None:
    chosen, fifo, lines = spin(1, 1e-3)
    if not fifo:
        pytest.skip("SCHED_FIFO is not allowed here: the spin is chosen only at SCHED_FIFO")
    assert chosen == FIFO_BUSY_WAIT_S
    assert f"busy-wait {1e6 * FIFO_BUSY_WAIT_S:g} us" in lines[-1]
    assert spin(3, 1e-3)[0] == FIFO_COMPOSED_BUSY_WAIT_S > FIFO_BUSY_WAIT_S
    # at 2 kHz the composed spin is held to its share of the period, without a line about it
    chosen, _, lines = spin(3, 5e-4)
    assert chosen == FIFO_BUSY_SHARE * 5e-4 and not any("at most" in line for line in lines)
    assert spin(3, 1e-3, busy_wait=1e-4)[0] == 1e-4
    # a given value equal to the normal-priority default is the user's, not "automatic"
    chosen, _, lines = spin(1, 1e-3, busy_wait=BUSY_WAIT_S)
    assert chosen == BUSY_WAIT_S and not any("at most" in line for line in lines)
    # one too large for the period is cut to its share, said in a line
    chosen, _, lines = spin(1, 1e-3, busy_wait=8e-4)
    assert chosen == FIFO_BUSY_SHARE * 1e-3 and any("busy_wait 0.0008 s at SCHED_FIFO" in line for line in lines)
    assert policy_of(0) == os.SCHED_OTHER  # each call's settings undone


def test_the_controller_ticks_at_the_highest_default_priority_the_plant_and_trajectory_below() -> None:
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    from pdsmc_ros.controller.node import ControllerNode
    from pdsmc_ros.loop.realtime_params import LoopReport
    from pdsmc_ros.mujoco_driver.node import MujocoDriverNode
    from pdsmc_ros.plant.node import PlantNode
    from pdsmc_ros.trajectory.node import TrajectoryNode

    ctx = Context()
    rclpy.init(context=ctx, domain_id=0)
    try:
        declared = {}
        for cls in (ControllerNode, PlantNode, MujocoDriverNode, TrajectoryNode):
            node = Node(f"priority_{cls.__name__.lower()}", context=ctx, start_parameter_services=False)
            wrapper = cls.__new__(cls)  # the node class's own attributes, without its run's set-up
            wrapper.node = node
            declared[cls.__name__] = (LoopReport(wrapper, "realtime").settings.thread_priority,
                                      node.get_parameter("thread_priority").value)
            lockstep = Node(f"lockstep_{cls.__name__.lower()}", context=ctx, start_parameter_services=False)
            wrapper.node = lockstep
            assert LoopReport(wrapper, "lockstep").settings.thread_priority == 0
            node.destroy_node()
            lockstep.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)
    # ros2_control's controller manager runs at 50; the hardware's stand-in and the reference below it
    assert declared == {"ControllerNode": (50, 50), "PlantNode": (49, 49), "MujocoDriverNode": (49, 49),
                        "TrajectoryNode": (48, 48)}
