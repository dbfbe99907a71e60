"""The graph recorder: a graph the package did not start, recorded as ``ros2 bag record`` records it.

Given ``topics``, ``actions`` or ``all_topics`` (:func:`declare_graph_parameters`), the recorder node
records a driver's ``/joint_states``, a controller's commands and state, an action's feedback,
status and results, ``/diagnostics``, ``/robot_description``, ``/tf``, each with the type the graph
gives it, until SIGINT or SIGTERM (docs/recording.md). Its subscriptions' serialized messages are
taken by a thread of its own from a wait set (:mod:`pdsmc_ros.rclpy_internals`).
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from action_msgs.msg import GoalStatus, GoalStatusArray
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.topic_endpoint_info import TopicEndpointInfo
from rosbags.typesys import Stores, get_typestore
from service_msgs.msg import ServiceEventInfo

from .. import rclpy_internals as _rclpy
from ..bag.cdr import decode_string
from ..bag.graph import RECORDING_KEY, deserialize
from ..bag.tf import TF_TYPE, TfRecorder
from ..bag.writer import MessageAppender, flush_chunk, open_new_bag
from ..errors import BagError, CdrError, ConfigError
from ..loop.lifecycle import EXIT_FAILURE, EXIT_OK
from ..parameters.descriptors import descriptor
from ..ros.topics import (
    STEADY_CLOCK,
    TOPIC_JOINT_STATES,
    TOPIC_ROBOT_DESCRIPTION,
)
from .graph_types import interface_class, message_class, type_definition

# topic -> (rclpy type, ROS type name, QoS)
from .output import FLUSH_PERIOD_S, BagOutput

GRAPH_PARAMETERS: dict[str, tuple[Any, Any]] = {
    "topics": (None, descriptor("graph mode: topics to record (a list of names), their types taken from the "
                                "graph as ros2 bag record takes them")),
    "actions": (None, descriptor("graph mode: actions (a list of names) whose feedback and status topics to "
                                 "record, and, with action_results, the result of each goal that ends")),
    "all_topics": (False, descriptor("graph mode: record every topic of the graph but hidden ones (a name "
                                     "part starting with _), as ros2 bag record -a")),
    "action_results": (True, descriptor(
        "graph mode: ask the server of each recorded action for the result of each goal that ends "
        "(get_result, as any action client may) and record the answer as that service's event "
        "(<action>/_action/get_result/_service_event)")),
    "tf_from_joint_states": (True, descriptor(
        "graph mode: with no /tf publisher in the graph, record /tf of the arm's links from the recorded "
        "/joint_states and /robot_description, as robot_state_publisher would (50 per second of the stamps)")),
    "discovery_period": (0.1, descriptor("graph mode: seconds between looks at the graph for new topics",
                                         lo=0.01, hi=10.0)),
}
"""The recorder's graph-mode parameters (declared beside ``output`` and the run's parameters)."""

TAKE_BATCH_S = 0.002  # graph mode: messages gather this long after a wake-up (a few hundred wake-ups a second)
TAKE_WAIT_S = 0.05  # graph mode: the longest wait for a message (new subscriptions are taken up this soon)
TAKE_MAX = 2000  # graph mode: messages of one topic written per pass (the others' turn comes between)
TERMINAL = (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED, GoalStatus.STATUS_ABORTED)


@dataclass
class GraphSettings:
    """What a graph recording records (the graph-mode parameters, checked)."""

    topics: list[str]
    actions: list[str]
    all_topics: bool
    action_results: bool
    tf_from_joint_states: bool
    discovery_period: float


def _names(node: Node, name: str) -> list[str]:
    value = node.get_parameter(name).value
    if value is None:
        return []
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) and v for v in value):
        raise ConfigError(f"parameter {name} must be a list of names, e.g. {name}:=\"['/joint_states']\", "
                          f"got {value!r}")
    try:
        return [node.resolve_topic_name(v) for v in value]
    except Exception as exc:  # noqa: BLE001 - rclpy raises several kinds for an invalid name
        raise ConfigError(f"parameter {name}: {value!r} holds an invalid name ({exc})") from None


def declare_graph_parameters(node: Node) -> GraphSettings | None:
    """Declare :data:`GRAPH_PARAMETERS`; the graph recording they ask for, or None (the pipeline's
    recorder). ConfigError naming a parameter with a bad value."""
    for name, (default, desc) in GRAPH_PARAMETERS.items():
        node.declare_parameter(name, default, desc)
    flags = {}
    for name in ("all_topics", "action_results", "tf_from_joint_states"):
        flags[name] = node.get_parameter(name).value
        if not isinstance(flags[name], bool):
            raise ConfigError(f"parameter {name} must be true or false, got {flags[name]!r}")
    period = node.get_parameter("discovery_period").value
    if isinstance(period, bool) or not isinstance(period, (int, float)) or not 0.01 <= period <= 10.0:
        raise ConfigError(f"parameter discovery_period must be a number of seconds in [0.01, 10], got {period!r}")
    settings = GraphSettings(_names(node, "topics"), _names(node, "actions"), flags["all_topics"],
                             flags["action_results"], flags["tf_from_joint_states"], float(period))
    if not (settings.topics or settings.actions or settings.all_topics):
        return None
    return settings


def default_bag_name() -> str:
    """``ros2 bag record``'s default bag directory: ``rosbag2_<date>-<time>`` here."""
    return time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S")


def recorded_qos(publishers: Sequence[TopicEndpointInfo]) -> QoSProfile:
    """A subscription that matches every publisher of a topic and keeps every sample (as
    ``ros2 bag record`` adapts its QoS to the publishers'): reliable unless one of them is best
    effort, transient local if all of them are (a latched topic's last message arrives), keep-all."""
    best_effort = any(p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for p in publishers)
    latched = all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publishers)
    return QoSProfile(history=HistoryPolicy.KEEP_ALL,
                      reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def _hidden(topic: str) -> bool:
    return any(part.startswith("_") for part in topic.split("/"))


def _taken_by_thread(_msg: bytes) -> None:  # pragma: no cover - never called
    """Callback of a recorded subscription: its messages are taken by the recorder's thread."""


@dataclass
class Recorded:
    """One recorded topic: its subscription, bag connection and count."""

    topic: str
    type_name: str
    subscription: Any
    append: Any  # MessageAppender.append_received of its connection
    count: int = 0


@dataclass
class ActionResults:
    """An action whose goals' results the recorder asks for (``action_results``)."""

    name: str
    client: Any
    event_type: Any  # the GetResult service's Event class
    append: Any
    event_name: str = ""
    asked: set[bytes] = field(default_factory=set)
    pending: list[bytes] = field(default_factory=list)
    answered: int = 0


class GraphRecorder(BagOutput):
    """Records the topics of a graph it did not start, as ``ros2 bag record`` does (graph mode).

    Topics are taken up as the graph shows them (every ``discovery_period``), each with the
    type its publishers give and a QoS that matches them all and keeps every sample
    (:func:`recorded_qos`). The subscriptions live on a lean node no executor sees; a thread of
    their own waits for their messages, lets them gather for a couple of milliseconds and
    writes each with its receive and send times (the middleware's) into the bag: nothing waits
    for the writing but the recorder, and a backlog is written in large batches. The flush
    timer closes a chunk every 0.5 s, so a killed recorder loses at most that much.
    """

    observer = True

    def __init__(self, node: Node, settings: GraphSettings) -> None:
        self.node = node
        self.settings = settings
        self.done = False
        self.exit_code = EXIT_OK
        output = str(node.get_parameter("output").value) or default_bag_name()
        try:
            self.writer: Any = open_new_bag(output)
        except ConfigError as exc:
            raise ConfigError(f"parameter output: {exc}") from None
        self.path = Path(output)
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        self.lock = threading.Lock()  # the writer: the taking thread, the flush timer, result answers
        self.recorded: dict[str, Recorded] = {}
        self.refused: set[str] = set()
        self.results: dict[str, ActionResults] = {}
        self.tf: TfRecorder | None = None
        self.tf_append: Any = None
        self.urdf: str | None = None  # the last /robot_description, until /tf is made from it
        self.io = Node(f"{node.get_name()}_io", namespace=node.get_namespace(), context=node.context,
                       use_global_arguments=False, start_parameter_services=False, enable_rosout=False)
        self.stopping = threading.Event()
        self.entries: list[Recorded] = []  # what the thread takes from (replaced, never changed in place)
        self.thread = threading.Thread(target=self._take_loop, name="recorder_take", daemon=True)
        self.thread.start()
        node.create_timer(settings.discovery_period, self.discover, clock=STEADY_CLOCK)
        node.create_timer(FLUSH_PERIOD_S, self.flush, clock=STEADY_CLOCK)
        wanted = [*settings.topics, *(f"{a} (action)" for a in settings.actions)]
        node.get_logger().info(f"recording {'every topic of the graph' if settings.all_topics else ''}"
                               f"{' and ' if settings.all_topics and wanted else ''}{', '.join(wanted)} "
                               f"into {self.path} (graph mode)")
        self.discover()

    # -- which topics ------------------------------------------------------- #
    def wanted(self, topic: str) -> bool:
        """Whether ``topic`` is one to record."""
        if topic in self.settings.topics:
            return True
        for action in self.settings.actions:
            rest = topic[len(action):] if topic.startswith(action + "/_action/") else ""
            if rest in ("/_action/feedback", "/_action/status") or rest.endswith("/_service_event"):
                return True
        return self.settings.all_topics and not _hidden(topic)

    def discover(self) -> None:
        """Subscribe to the wanted topics the graph shows now (a topic waits for its first publisher:
        its QoS is the publishers'); then ask for the results of goals that ended."""
        log = self.node.get_logger()
        added = False
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.recorded or topic in self.refused or not self.wanted(topic):
                continue
            if len(types) != 1:
                log.error(f"{topic} is published with several types ({', '.join(types)}): not recorded")
                self.refused.add(topic)
                continue
            publishers = self.node.get_publishers_info_by_topic(topic)
            if not publishers:
                continue
            try:
                added |= self._subscribe(topic, types[0], publishers)
            except (ConfigError, BagError, OSError) as exc:
                log.error(f"{topic} ({types[0]}) not recorded: {exc}")
                self.refused.add(topic)
        if added:
            self.entries = list(self.recorded.values())
        self._ask_results()

    def _subscribe(self, topic: str, type_name: str, publishers: Sequence[TopicEndpointInfo]) -> bool:
        cls = message_class(type_name)
        msgdef, rihs01 = type_definition(self.typestore, type_name)
        with self.lock:
            connection = self.writer.add_connection(topic, type_name, msgdef=msgdef, rihs01=rihs01)
            append = MessageAppender(self.writer, connection).append_received
        qos = recorded_qos(publishers)
        subscription = self.io.create_subscription(cls, topic, _taken_by_thread, qos, raw=True)
        self.recorded[topic] = Recorded(topic, type_name, subscription, append)
        self.node.get_logger().info(f"recording {topic} ({type_name}, {qos.reliability.name.lower()}, "
                                    f"{qos.durability.name.lower()}, keep all)")
        if self.settings.action_results and topic.endswith("/_action/status"):
            self._watch_results(topic[: -len("/_action/status")])
        return True

    # -- taking and writing (the recorder's thread) ------------------------- #
    def _take_loop(self) -> None:
        context = self.io.context
        entries: list[Recorded] = []
        wait_set: Any = None
        handles: list[Any] = []
        while not self.stopping.is_set() and context.ok():
            if entries is not self.entries:
                entries = self.entries
                wait_set = _rclpy.SubscriptionWaitSet(len(entries), 0, context) if entries else None
                handles = [entry.subscription.handle for entry in entries]
            if wait_set is None:
                time.sleep(TAKE_WAIT_S)
                continue
            wait_set.wait(handles, int(TAKE_WAIT_S * 1e9))
            time.sleep(TAKE_BATCH_S)
            self._take(entries)
        self._take(self.entries)  # what arrived up to the stop

    def _take(self, entries: Sequence[Recorded]) -> None:
        for entry in entries:
            take = _rclpy.take_raw(entry.subscription)
            while True:
                batch = []
                while len(batch) < TAKE_MAX:
                    taken = take()
                    if taken is None:
                        break
                    data, info = taken
                    batch.append((data, info.get("received_timestamp") or time.time_ns(),
                                  info.get("source_timestamp") or 0))
                if not batch:
                    break
                self._write(entry, batch)

    def _write(self, entry: Recorded, batch: list[tuple[bytes, int, int]]) -> None:
        try:
            with self.lock:
                if self.writer is None:
                    return
                entry.append(batch)
                entry.count += len(batch)
                if entry.topic == "/" + TOPIC_ROBOT_DESCRIPTION:
                    with contextlib.suppress(CdrError):  # a malformed one is recorded as received, no /tf
                        self.urdf = decode_string(batch[-1][0])
                if self.tf is not None and entry.topic == "/" + TOPIC_JOINT_STATES:
                    frames = self.tf.messages([data for data, _, _ in batch])
                    if frames:
                        self.tf_append.append_many(time.time_ns(), frames)
        except OSError as exc:
            self.write_failed(exc)
            return
        if entry.topic.endswith("/_action/status"):
            self._statuses(entry.topic[: -len("/_action/status")], batch[-1][0])

    # -- action results ----------------------------------------------------- #
    def _watch_results(self, action: str) -> None:
        """Ask ``action``'s server for its goals' results: its type from its feedback topic."""
        if action in self.results:
            return
        found = dict(self.node.get_topic_names_and_types()).get(f"{action}/_action/feedback", [])
        names = [t for t in found if t.endswith("_FeedbackMessage")]
        if not names:
            return  # the feedback topic is not there yet: the next status asks again
        action_type = names[0][: -len("_FeedbackMessage")]
        try:
            action_class = interface_class(action_type)
            event_name = f"{action_type}_GetResult_Event"
            msgdef, rihs01 = type_definition(self.typestore, event_name)
        except ConfigError as exc:
            self.node.get_logger().error(f"{action}: results not recorded: {exc}")
            self.results[action] = ActionResults(action, None, None, None)
            return
        topic = f"{action}/_action/get_result/_service_event"
        with self.lock:
            connection = self.writer.add_connection(topic, event_name, msgdef=msgdef, rihs01=rihs01)
        client = self.node.create_client(action_class.Impl.GetResultService, f"{action}/_action/get_result")
        self.results[action] = ActionResults(action, client, action_class.Impl.GetResultService.Event,
                                             MessageAppender(self.writer, connection).append_received, event_name)
        self.node.get_logger().info(f"recording {action}'s goal results on {topic} (asked of its server)")

    def _statuses(self, action: str, data: bytes) -> None:
        """A status message: the goals that ended are due for their result (taking thread)."""
        watch = self.results.get(action)
        if watch is None or watch.client is None:
            return
        try:
            status = deserialize_message(data, GoalStatusArray)
        except Exception:  # noqa: BLE001 - a malformed message is recorded as it is, not acted on
            return
        for goal in status.status_list:
            uuid = bytes(goal.goal_info.goal_id.uuid)
            if goal.status in TERMINAL and uuid not in watch.asked:
                watch.asked.add(uuid)
                watch.pending.append(uuid)

    def _ask_results(self) -> None:
        for watch in list(self.results.values()):
            if watch.client is None:
                continue
            while watch.pending:
                uuid = watch.pending.pop(0)
                request = watch.client.srv_type.Request()
                request.goal_id.uuid = list(uuid)
                future = watch.client.call_async(request)
                future.add_done_callback(lambda f, w=watch, r=request: self._answer(w, r, f))
        if self.settings.tf_from_joint_states and self.tf is None and self.urdf is not None:
            self._start_tf()

    def _answer(self, watch: ActionResults, request: Any, future: Any) -> None:
        """A result answered: recorded as the GetResult service's response event."""
        response = future.result()
        if response is None:
            return
        sec, nanosec = divmod(time.time_ns(), 1_000_000_000)
        event = watch.event_type(request=[request], response=[response])
        event.info = ServiceEventInfo(event_type=ServiceEventInfo.RESPONSE_RECEIVED)
        event.info.stamp.sec, event.info.stamp.nanosec = sec, nanosec
        event.info.sequence_number = watch.answered
        watch.answered += 1
        now = time.time_ns()
        data = serialize_message(event)
        try:  # without the stray bytes rclpy's serializer leaves after some messages (bag.graph.deserialize)
            data = data[: deserialize(self.typestore, data, watch.event_name)[1]]
        except Exception as exc:  # noqa: BLE001 - not one of ours: recorded as rclpy gave it
            self.node.get_logger().warn(f"{watch.name}: a result event left as serialized ({exc})")
        try:
            with self.lock:
                if self.writer is not None:
                    watch.append([(data, now, now)])
        except OSError as exc:
            self.write_failed(exc)

    # -- /tf from the joint states ------------------------------------------ #
    def _start_tf(self) -> None:
        """/tf as robot_state_publisher would publish it, once the arm's URDF has been recorded
        (and only if nothing in the graph publishes /tf)."""
        if "/" + TOPIC_JOINT_STATES not in self.recorded or self.node.count_publishers("/tf") \
                or "/tf" in self.recorded:
            return
        urdf, self.urdf = self.urdf, None  # tried once per description
        try:
            tf = TfRecorder(str(urdf))
        except Exception as exc:  # noqa: BLE001 - a URDF LinkFrames cannot read: recorded without /tf
            self.node.get_logger().warn(f"no /tf from the joint states: {exc}")
            return
        with self.lock:
            typestore = get_typestore(Stores.ROS2_JAZZY)
            self.tf_append = MessageAppender(self.writer, self.writer.add_connection("/tf", TF_TYPE,
                                                                                     typestore=typestore))
            static = self.writer.add_connection("/tf_static", TF_TYPE, typestore=typestore)
            MessageAppender(self.writer, static).append_many(time.time_ns(), [tf.static_message()])
            self.tf = tf
        self.node.get_logger().info("recording /tf of the arm's links from /joint_states and /robot_description")

    def close(self) -> None:
        """Take what has arrived, then finish the bag; idempotent."""
        if self.writer is None:
            return
        self.stopping.set()
        self.thread.join(timeout=5.0)
        recording = {"recorder": "graph", "topics": {e.topic: e.type_name for e in self.recorded.values()},
                     "actions": self.settings.actions, "counts": {e.topic: e.count for e in self.recorded.values()}}
        try:
            with self.lock:
                self.writer.set_custom_data(RECORDING_KEY, json.dumps(recording, sort_keys=True))
                flush_chunk(self.writer)
                self.writer.close()
        except OSError as exc:
            self.node.get_logger().error(f"closing {self.path} failed: {exc}")
            self.exit_code = EXIT_FAILURE
        with self.lock:
            self.writer = None
        self.io.destroy_node()
        summary = ", ".join(f"{e.topic} {e.count}" for e in self.recorded.values()) or "no topic"
        answered = sum(w.answered for w in self.results.values())
        print(f"recorder: wrote {self.path}: {summary}" + (f"; {answered} goal results" if self.results else ""),
              flush=True)
