"""The controller's parameter services served in the goal process (:class:`ParameterStandIn`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


class ParameterStandIn:
    """The controller's parameter services (``/<controller>/get_parameters``, ``set_parameters``,
    ...), served in the goal process on a node of its own that declares the controller's
    parameters as they are (:func:`~.goal_process.parameter_table`) and guards them with the controller's own
    callbacks: the tables' checks (:func:`~pdsmc_ros.parameters.ros.guard_run_parameters`; rclpy
    refuses read-only ones and wrong types from their descriptors) and the gains' resolver and
    stability check (:class:`~pdsmc_ros.controller.parameters.GainUpdates`, here in this process). Gains it accepts
    are sent to the loop's process (``("gains", gains, given)``), which applies them in its spare
    time. ``ros2 param set`` at ten sets a second held the loop's interpreter lock 1-3 ms a set
    (rclpy's conversions, the callbacks) and kept the loop's p99 lateness at 1.5-2.2 times idle.

    Events on ``/parameter_events`` name the controller, as its own would.
    """

    def __init__(self, setup: dict[str, Any], context: Any, send: Callable[[object], None]) -> None:
        from rcl_interfaces.msg import Parameter as ParameterMsg
        from rcl_interfaces.msg import ParameterDescriptor
        from rclpy.parameter import Parameter
        from rclpy.parameter_service import ParameterService
        from rclpy.serialization import deserialize_message

        from ...control.stability import check_rate
        from ...parameters.ros import guard_run_parameters
        from ...rclpy_internals import announce, node_announcing_as
        from ..parameters import GainUpdates

        table = [(Parameter.from_parameter_msg(deserialize_message(value, ParameterMsg)),
                  deserialize_message(descriptor, ParameterDescriptor)) for value, descriptor in setup["parameters"]]
        self.node = node = node_announcing_as(
            setup["base"], f"{setup['name']}_parameters", namespace=setup["namespace"], context=context,
            use_global_arguments=False, start_parameter_services=False, enable_rosout=False,
            parameter_overrides=[p for p, _ in table if p.type_ != Parameter.Type.NOT_SET])
        for parameter, descriptor in table:
            if not node.has_parameter(parameter.name):
                unset = parameter.type_ == Parameter.Type.NOT_SET and descriptor.type != Parameter.Type.NOT_SET
                node.declare_parameter(parameter.name, Parameter.Type(descriptor.type) if unset else parameter.value,
                                       descriptor)
        announce(node)  # from now on: the controller announced its own declarations
        spec = setup["spec"]
        guard_run_parameters(node, spec.controller, gains=True)
        reference, stability = spec.reference(), setup["stability"] or {}
        self.gains = GainUpdates(node, spec, lambda new: check_rate(new, reference, **stability),
                                 lambda gains: send(("gains", gains, self.gains.given)),
                                 joint_map=setup["joint_map"])
        self.named = _Named(node, setup["name"])  # ParameterService keeps a weak reference to it
        self.service = ParameterService(self.named)
        self.spinner: Any = None

    def spin(self) -> None:
        """Serve from now on, in a thread of its own (the action's server, later, has its own)."""
        from rclpy.executors import SingleThreadedExecutor

        from ...loop.executor_thread import ExecutorThread

        executor = SingleThreadedExecutor(context=self.node.context)
        executor.add_node(self.node)
        self.spinner = ExecutorThread(executor, self.node, name="parameters")

    def destroy(self) -> None:
        if self.spinner is not None:
            self.spinner.stop()
            self.spinner.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()


class _Named:
    """``node`` as rclpy's ParameterService sees it: its services named after ``name``."""

    def __init__(self, node: Any, name: str) -> None:
        self._node = node
        self._name = name

    def get_name(self) -> str:
        return self._name

    def __getattr__(self, attribute: str) -> Any:
        return getattr(self._node, attribute)
