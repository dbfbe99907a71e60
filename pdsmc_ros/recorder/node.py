"""Recorder node: writes every run topic into a rosbag2 MCAP bag.

Serialized (raw) subscriptions are written as they arrive into rosbags'
writer in MCAP mode (through :class:`~pdsmc_ros.bag.writer.MessageAppender`,
which writes rosbags' bytes without its per-message overhead), so the bag
holds exactly the CDR bytes that crossed DDS (or, composed with
``--intra-process``, that the publisher handed over). The recorder is an
observer: it takes its messages in batches of about 2 ms, and a message's log
time is when its batch was taken; the run's timing lives in the header stamps.
The run description (robot, contour, controller, gains, rates, scenario,
package version) is stored twice: as the latched ``/pdsmc/run_description``
message, written to disk as soon as it arrives (as is every topic's first
batch), and in ``metadata.yaml``'s custom data, so analysis needs nothing
else. The bag is closed cleanly on completion, SIGINT or SIGTERM.

Given ``topics``, ``actions`` or ``all_topics``, the recorder records a graph it did not
start instead (:class:`GraphRecorder`, docs/recording.md): a driver's ``/joint_states``, a
controller's commands and state, an action's feedback, status and results, ``/diagnostics``,
``/robot_description``, ``/tf``, each with the type the graph gives it, as ``ros2 bag record``
does, until SIGINT or SIGTERM.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from trajectory_msgs.msg import JointTrajectory

from ..bag.reader import DESCRIPTION_KEY, RECORDER_DESCRIPTION_TOPIC
from ..bag.tf import TF_TYPE, TfRecorder
from ..bag.writer import MessageAppender, RunProgress, open_new_bag
from ..errors import ConfigError
from ..loop.inputs import Inputs
from ..loop.lifecycle import EXIT_FAILURE, EXIT_OK
from ..loop.process import run_node
from ..parameters import RECORDER
from ..parameters.ros import declare
from ..ros.node_run import declare_node_run, description_json
from ..ros.topics import (
    LATCHED_QOS,
    LOCKSTEP_QOS,
    STEADY_CLOCK,
    TOPIC_DESCRIPTION,
    TOPIC_DIAGNOSTICS,
    TOPIC_EE_ACTUAL,
    TOPIC_EE_DESIRED,
    TOPIC_EFFORT,
    TOPIC_JOINT_STATES,
    TOPIC_REFERENCE,
    TOPIC_ROBOT_DESCRIPTION,
    TOPIC_TIMING,
)
from ..runs.builder import control_steps
from .graph import GraphRecorder, declare_graph_parameters
from .output import FLUSH_PERIOD_S, BagOutput

# topic -> (rclpy type, ROS type name, QoS)
RECORDED = {
    TOPIC_JOINT_STATES: (JointState, "sensor_msgs/msg/JointState", LOCKSTEP_QOS),
    TOPIC_REFERENCE: (JointTrajectory, "trajectory_msgs/msg/JointTrajectory", LOCKSTEP_QOS),
    TOPIC_EFFORT: (Float64MultiArray, "std_msgs/msg/Float64MultiArray", LOCKSTEP_QOS),
    TOPIC_EE_DESIRED: (PointStamped, "geometry_msgs/msg/PointStamped", LOCKSTEP_QOS),
    TOPIC_EE_ACTUAL: (PointStamped, "geometry_msgs/msg/PointStamped", LOCKSTEP_QOS),
    TOPIC_TIMING: (Float64MultiArray, "std_msgs/msg/Float64MultiArray", LOCKSTEP_QOS),
    TOPIC_DIAGNOSTICS: (DiagnosticArray, "diagnostic_msgs/msg/DiagnosticArray", LOCKSTEP_QOS),
    TOPIC_DESCRIPTION: (String, "std_msgs/msg/String", LATCHED_QOS),
    TOPIC_ROBOT_DESCRIPTION: (String, "std_msgs/msg/String", LATCHED_QOS),
}
RECORDER_BATCH_S = 0.002  # the recorder wakes at most ~500 times a second (bench/lockstep.py)
STEPPED = (TOPIC_JOINT_STATES, TOPIC_REFERENCE, TOPIC_EFFORT, TOPIC_EE_DESIRED, TOPIC_EE_ACTUAL)
"""Topics with one message per control step; the run is complete when each has its last."""


class RecorderNode(BagOutput):
    """Thin wrapper: raw subscriptions into a rosbags MCAP writer."""

    observer = True  # takes the real-time parameters with normal scheduling by default (cpu_affinity)

    def __init__(self, node: Node | None = None) -> None:
        self.node = node = Node("recorder") if node is None else node
        run = declare_node_run(node)
        self.spec = run.spec
        output = declare(node, RECORDER)["output"]  # read-only, as the run's (declare_node_run guards them)
        try:
            self.writer = open_new_bag(output)
        except ConfigError as exc:
            raise ConfigError(f"parameter output: {exc}") from None
        self.path = Path(output)
        self.progress = RunProgress(STEPPED, TOPIC_EFFORT, control_steps(self.spec.contour_model().duration,
                                                                          self.spec.rate), self.spec.rate)
        self.done = False
        self.exit_code = EXIT_OK
        self.description: str | None = None
        self.counts = dict.fromkeys(RECORDED, 0)
        typestore = get_typestore(Stores.ROS2_JAZZY)
        self.connections = {}
        # the flush timer may run in the executor's thread (real-time composed mode)
        self.lock = threading.Lock()
        # off the loop's critical path: take messages in batches (keep-all subscriptions)
        self.inputs = Inputs(node, run.mode, batch_s=RECORDER_BATCH_S)
        for topic, (msg_type, type_name, qos) in RECORDED.items():
            name = "/" + topic
            self.connections[topic] = self.writer.add_connection(name, type_name, typestore=typestore)
            self.inputs.subscribe(msg_type, topic, self._callback(topic), qos)
        # the arm's link frames from the recorded states (bags that show the arm moving)
        self.tf = TfRecorder(self.spec.robot_description())
        self.tf_append = MessageAppender(self.writer, self.writer.add_connection("/tf", TF_TYPE, typestore=typestore))
        static = self.writer.add_connection("/tf_static", TF_TYPE, typestore=typestore)
        MessageAppender(self.writer, static).append_many(time.time_ns(), [self.tf.static_message()])
        # the run as this recorder's parameters describe it, on disk now with the MCAP header:
        # a bag from any moment on names its run, even before the controller's description
        # (with its gains) has been discovered and received
        own = self.writer.add_connection(RECORDER_DESCRIPTION_TOPIC, "std_msgs/msg/String", typestore=typestore)
        MessageAppender(self.writer, own).append_many(
            time.time_ns(), [serialize_message(String(data=description_json(self.spec, run.mode)))])
        self.flush()
        # rosbags closes an MCAP chunk only at 1 MiB (seconds of data); close and flush one
        # every 0.5 s so a killed recorder loses at most that much (see bag/mcapscan.py)
        self.flush_timer = node.create_timer(FLUSH_PERIOD_S, self.flush, clock=STEADY_CLOCK)
        node.get_logger().info(f"recording {len(RECORDED)} topics into {self.path}")

    def _callback(self, topic: str):  # noqa: ANN202
        append_many = MessageAppender(self.writer, self.connections[topic]).append_many
        stepped = topic in STEPPED

        def callback(batch: list[bytes]) -> None:
            """A batch of one topic's messages, in arrival order (taken now: one receive time)."""
            try:
                with self.lock:
                    append_many(time.time_ns(), batch)
                    if topic == TOPIC_JOINT_STATES and (frames := self.tf.messages(batch)):
                        self.tf_append.append_many(time.time_ns(), frames)
            except OSError as exc:
                self.write_failed(exc)
                return
            first = not self.counts[topic]
            self.counts[topic] += len(batch)
            if topic == TOPIC_DESCRIPTION:
                self.description = deserialize_message(batch[-1], String).data
            if first:
                # a topic's first messages (the run description above all) go to disk at once,
                # so a recorder killed at any moment after start leaves a bag that names its run
                self.flush()
                self.node.get_logger().info(f"first message on /{topic} is on disk")
            if stepped and self.progress.batch(topic, batch):
                self.done = True

        return callback

    def close(self) -> None:
        """Finish the bag (metadata and MCAP summary); idempotent."""
        if self.writer is None:
            return
        if self.description is not None:
            self.writer.set_custom_data(DESCRIPTION_KEY, self.description)
        self.flush()  # the last chunk too with its CRC (rosbags' own close would write none)
        try:
            self.writer.close()
        except OSError as exc:
            self.node.get_logger().error(f"closing {self.path} failed: {exc}")
            self.exit_code = EXIT_FAILURE
        self.writer = None
        summary = ", ".join(f"/{t} {c}" for t, c in self.counts.items() if c)
        print(f"recorder: wrote {self.path}: {summary}", flush=True)




def make_recorder() -> Any:
    """The recorder ``ros2 run pdsmc_ros recorder`` starts: the graph recorder when its parameters
    name what to record (:func:`declare_graph_parameters`), else the pipeline's."""
    node = Node("recorder")
    settings = declare_graph_parameters(node)
    if settings is None:
        return RecorderNode(node)
    node.declare_parameter("output", "")
    return GraphRecorder(node, settings)


def main(args: Sequence[str] | None = None) -> int:
    return run_node("recorder", make_recorder, args)


if __name__ == "__main__":
    sys.exit(main())
