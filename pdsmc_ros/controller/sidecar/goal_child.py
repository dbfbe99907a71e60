"""The goal process's program (``python -m pdsmc_ros.controller.sidecar.goal_child``): the
controller's action server (:class:`~pdsmc_ros.controller.action.FollowJointTrajectoryServer`) on
its stand-in of the controller (:class:`~.remote_view.RemoteView`) and its parameter services
(:class:`~.parameter_stand_in.ParameterStandIn`), speaking with the loop's process
(:class:`~.goal_process.GoalProcess`) in :mod:`.framing`'s frames until its input closes."""

from __future__ import annotations

import contextlib
import queue
import sys
import threading
from typing import Any

from ...robots.registry import find_robot, register_robot
from .framing import FrameReader, frame, write_all
from .parameter_stand_in import ParameterStandIn
from .process import as_child
from .remote_view import RemoteView


def main() -> None:
    """The child: the setup first, then the loop's messages until its input closes."""
    as_child()
    # everything imported before the setup arrives: a spare child waits here, ready in a fraction of a start
    import rclpy
    from rclpy.parameter import Parameter
    from rclpy.serialization import deserialize_message
    from rclpy.signals import SignalHandlerOptions
    from trajectory_msgs.msg import JointTrajectory

    from ...control import stability  # noqa: F401 - the parameter stand-in's gain check
    from ...parameters import ros as _guards  # noqa: F401 - the parameter stand-in's guards
    from ...ros.topics import TOPIC_JOINT_TRAJECTORY
    from .. import parameters as _gain_parameters  # noqa: F401 - the parameter stand-in's gains
    from ..action import FollowJointTrajectoryServer, topic_trajectory

    # ... and its DDS participant made and discovered (a hidden node holds it): a replacement's services
    # then need only their own endpoints matched by a client, not a new participant found first
    context = rclpy.Context()
    rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
    participant = rclpy.create_node("_goal_process", context=context, start_parameter_services=False,
                                    enable_rosout=False)
    inbox = FrameReader(sys.stdin.fileno())
    first = inbox.read_blocking()
    if not first:
        participant.destroy_node()
        rclpy.shutdown(context=context)
        return
    setup: dict[str, Any] = first.pop(0)  # type: ignore[assignment]
    spec = setup["spec"]
    if setup["arm"] is not None and find_robot(spec.robot) is None:
        register_robot(setup["arm"], config=setup["config"])

    out = sys.stdout.fileno()
    write_lock = threading.Lock()

    def send(message: object) -> None:
        data = frame(message)
        with write_lock, contextlib.suppress(OSError):  # the loop's process gone: it ends this one too
            write_all(out, data)

    view = RemoteView(setup, context, send)
    parameters = ParameterStandIn(setup, context, send) if setup["parameters"] else None
    if parameters is not None:
        parameters.spin()
    server: FollowJointTrajectoryServer | None = None

    def serve() -> FollowJointTrajectoryServer:
        """The action, ~/query_state and the state's messages, from the loop's word ("serve": at
        start once the controller is active, so that a client that sees the server finds it active)."""
        overrides = [Parameter("use_sim_time", value=bool(setup["use_sim_time"]))]
        made = FollowJointTrajectoryServer(view, parameter_overrides=overrides, takes_topic=False,
                                           event_sink=lambda data: send(("publish", "goal_event", data)),
                                           state_sink=lambda data: send(("publish", "controller_state", data)))
        view.clock = made.node.get_clock()
        return made
    # ~/joint_trajectory messages, in order, in a thread of their own: their validation asks the
    # loop's process for its state, which this (reading) thread receives
    trajectories: queue.Queue[Any] = queue.Queue()

    serving = threading.Event()  # what arrived before waits for the server (the loop had no state yet)

    def take_trajectories() -> None:
        serving.wait()
        while (item := trajectories.get()) is not None:
            data, times = item
            try:
                msg = deserialize_message(data, JointTrajectory)
            except Exception as exc:  # noqa: BLE001 - any malformed message: refused, never fatal
                if server is not None:
                    server.report.report("error", f"{view.resolve(TOPIC_JOINT_TRAJECTORY)}: malformed message "
                                                  f"({exc})")
                continue
            if server is not None:  # forwarded only once the child serves
                topic_trajectory(view, msg, times, server.report)

    worker = threading.Thread(target=take_trajectories, name="joint_trajectory", daemon=True)
    worker.start()
    send(("ready",))
    try:
        for message in first:
            view.hear(message)
        while True:
            messages = inbox.read_blocking()
            if not messages:
                break  # the controller's process is gone or stopping
            news = False
            for message in messages:
                if message[0] == "trajectory":  # type: ignore[index]
                    trajectories.put(message[1:])  # type: ignore[index]
                    continue
                if message == ("serve",):
                    if server is None:
                        server = serve()
                        serving.set()
                    send(("serving",))
                    continue
                news = view.hear(message) or news
            if news and server is not None:
                server.state.send(float("inf"), list(server.goals.values()))
    finally:
        trajectories.put(None)
        serving.set()
        worker.join(timeout=2.0)
        if server is not None:
            server.stop()
        if parameters is not None:
            parameters.destroy()
        participant.destroy_node()
        with contextlib.suppress(Exception):
            rclpy.shutdown(context=context)


if __name__ == "__main__":
    main()
