"""The result of a goal lost with the goal process, answered to the client that waits for it.

A FollowJointTrajectory client (rclpy's ``ActionClient``, MoveIt's executor) asks for a goal's
result once, as soon as the goal is accepted, and waits: the action server holds the request until
the goal ends. With a goal process (:mod:`.goal_process`), that server lives in the child; a child
that is killed, crashes or is stopped takes the held request with it, and the server of the child
that replaces it never saw it (a service's requests are not kept for a reader that joins later).

So the controller's process offers the action's ``get_result`` service too, a second server of it
on a hidden node no executor spins. A client's request reaches every server of a service (DDS
delivers it to every matched reader) and the client takes the first answer; while the goal process
serves, its server answers and this one only keeps the requests (:meth:`LostResults.gather`, the
goal process's watching thread, every 0.1 s). When the child is lost, the loop ends its goal aborted
(:meth:`.goal_process.GoalProcess._lose`) and tells the outcome here (:meth:`LostResults.lose`);
the watching thread then answers the kept requests of that goal, and any that arrives until the
new child serves, with it: status ``ABORTED``, the ``error_string`` saying that the goal process
ended and how. A request that arrives once the new child serves is the new server's, which
answers it as rclpy answers a goal it does not know (``STATUS_UNKNOWN``).

joint_trajectory_controller has no such case (its action server and its loop share one process);
this keeps its contract -- every accepted goal ends with a result the client receives -- across the
process boundary the real-time controller adds.
"""

from __future__ import annotations

import collections
import threading
from typing import Any

from action_msgs.msg import GoalStatus
from control_msgs.action import FollowJointTrajectory
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from ...rclpy_internals import take_request
from ..goals import Outcome

KEPT_REQUESTS = 64
"""Goals whose result requests are kept, the newest (one goal runs at a time; a client asks once)."""
KEPT_LOST = 16
"""Lost goals whose outcome is kept for requests that arrive until the new child serves."""
STATUS = {"succeeded": GoalStatus.STATUS_SUCCEEDED, "canceled": GoalStatus.STATUS_CANCELED,
          "aborted": GoalStatus.STATUS_ABORTED}
"""An :class:`~pdsmc_ros.controller.goals.Outcome`'s status as ``action_msgs/GoalStatus``'s."""


class LostResults:
    """The ``get_result`` service of ``{base}/follow_joint_trajectory`` in the controller's process.

    Parameters
    ----------
    node : rclpy.node.Node
        The controller's node: its context, name and namespace (the service lives on a hidden
        companion node, ``_<name>_results``, that no executor spins).
    base : str
        The controller's fully qualified name: the action is ``{base}/follow_joint_trajectory``.
    """

    def __init__(self, node: Node, base: str) -> None:
        self.node = Node(f"_{node.get_name()}_results", namespace=node.get_namespace(), context=node.context,
                         use_global_arguments=False, start_parameter_services=False, enable_rosout=False)
        service_type = FollowJointTrajectory.Impl.GetResultService
        self.response_type = service_type.Response
        # deeper than the services' default (10): requests wait here until a gather, never lost to a burst
        qos = QoSProfile(depth=KEPT_REQUESTS, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
        self.service = self.node.create_service(service_type, f"{base}/follow_joint_trajectory/_action/get_result",
                                                _taken_by_gather, qos_profile=qos)
        self.lock = threading.Lock()
        self.waiting: collections.OrderedDict[bytes, list[Any]] = collections.OrderedDict()  # goal id: headers
        self.lost: collections.OrderedDict[bytes, Outcome] = collections.OrderedDict()

    def lose(self, key: bytes, outcome: Outcome) -> None:
        """The goal ``key`` (its id's bytes) ended with ``outcome`` because its process was lost (the
        loop's thread: only a dictionary's update under a lock)."""
        with self.lock:
            self.lost[key] = outcome
            while len(self.lost) > KEPT_LOST:
                self.lost.popitem(last=False)

    def served(self) -> None:
        """A new child serves the action: requests from now on are its server's."""
        with self.lock:
            self.lost.clear()

    def gather(self) -> int:
        """Take every waiting request (the watching thread): a lost goal's answered, the others kept;
        how many were answered."""
        answered = 0
        while (taken := take_request(self.service)) is not None:
            request, header = taken
            key = bytes(request.goal_id.uuid)
            with self.lock:
                outcome = self.lost.get(key)
                if outcome is None:
                    self.waiting.setdefault(key, []).append(header)
                    self.waiting.move_to_end(key)
                    while len(self.waiting) > KEPT_REQUESTS:
                        self.waiting.popitem(last=False)
                    continue
            answered += self._answer(outcome, [header])
        with self.lock:
            due = [(self.lost[key], self.waiting.pop(key)) for key in list(self.waiting) if key in self.lost]
        for outcome, headers in due:
            answered += self._answer(outcome, headers)
        return answered

    def _answer(self, outcome: Outcome, headers: list[Any]) -> int:
        response = self.response_type(status=STATUS[outcome.status], result=FollowJointTrajectory.Result(
            error_code=outcome.error_code, error_string=outcome.error_string))
        for header in headers:
            self.service.send_response(response, header)
        return len(headers)

    def destroy(self) -> None:
        self.node.destroy_node()


def _taken_by_gather(_request: Any, response: Any) -> Any:  # pragma: no cover - never called
    """The service's callback: no executor spins its node; :meth:`LostResults.gather` takes its requests."""
    return response
