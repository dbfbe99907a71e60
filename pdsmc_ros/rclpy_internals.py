"""Every private name of rclpy (and of its rcl bindings) the package uses, in one place.

rclpy's public API has no way to take a subscription's serialized messages in a wait set of one's
own, to trigger a guard condition that belongs to no node, to write a log line without rclpy's
per-call caller lookup, or to read and rewrite the parameter overrides a node was started with.
The package needs each (the serve loop, the recorder, the intra-process routes, the loop's log,
the parameter tables' start-up check); this module is where they are taken from rclpy, so an rclpy
update that changes them breaks here, named, and nowhere else: ``test/test_rclpy_internals.py``
fails with this module's name and what is missing (:func:`missing`).

Written against rclpy :data:`WRITTEN_AGAINST` (ROS 2 Jazzy). Where the public API can do the same,
it is used (:func:`declared_value`) or taken as the fallback (:func:`rcutils_log` is None without
the private writer: the caller logs through rclpy's logger).

The goal process's parameter stand-in needs two more: every parameter a node declared, unset
typed ones included (:func:`declared_parameters`), and a node whose ``/parameter_events`` name
another node, silent until told (:func:`node_announcing_as`, :func:`announce`).

The command's writer thread publishes serialized bytes with the interpreter lock released, which
rclpy's ``publish`` never does: :class:`SerializedPublish` calls rcl's
``rcl_publish_serialized_message`` through ctypes on the publisher's private handle pointer.

Every call on a private handle is made here too, or bound here once: the serve loop and the
recorder wait on their subscriptions with a :class:`SubscriptionWaitSet` (woken by a :class:`WakeUp`
from another thread) and take their messages with :func:`take_raw`; the guarded publishers write
serialized bytes with :func:`raw_publisher`.

The controller's process keeps the result requests of the goal process's goals, taking them from a
service no executor spins (:func:`take_request`): rclpy takes a service's requests only in its
executor.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.metadata
import os
from typing import Any

from rclpy.exceptions import ParameterNotDeclaredException, ParameterUninitializedException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter

WRITTEN_AGAINST = "7.1.5"
"""The rclpy release this module was written and tested against (ROS 2 Jazzy's)."""

RCLError = _rclpy.RCLError
"""What rcl's bindings raise (a publish on a destroyed publisher, say)."""

USED = {
    "rclpy.impl.implementation_singleton.rclpy_implementation": (
        "WaitSet", "GuardCondition", "RCLError", "rclpy_logging_rcutils_log"),
    "rclpy_implementation.WaitSet": ("clear_entities", "add_subscription", "add_guard_condition", "wait"),
    "rclpy_implementation.GuardCondition": ("trigger_guard_condition", "destroy_when_not_in_use"),
    "rclpy_implementation.Subscription": ("take_message",),
    "rclpy_implementation.Publisher": ("publish_raw", "pointer"),
    "rclpy_implementation.Service": ("service_take_request",),
    "rclpy.node.Node (an instance)": ("_parameter_overrides", "_parameters", "_parameter_event_publisher"),
}
"""Every private name used, by what holds it: the C extension's classes and functions, the methods
called on a subscription's or publisher's ``handle`` (``take_message(msg_type, raw)``: the
recorder and the serve loop take serialized messages; ``publish_raw``: the guarded publishers),
a node's parameter overrides, its declared parameters and its ``/parameter_events`` writer."""


def missing(node: Node | None = None) -> list[str]:
    """The names of :data:`USED` this rclpy lacks (``node``: an instance to check the node's names on)."""
    holders: dict[str, Any] = {
        "rclpy.impl.implementation_singleton.rclpy_implementation": _rclpy,
        "rclpy_implementation.WaitSet": getattr(_rclpy, "WaitSet", None),
        "rclpy_implementation.GuardCondition": getattr(_rclpy, "GuardCondition", None),
        "rclpy_implementation.Subscription": getattr(_rclpy, "Subscription", None),
        "rclpy_implementation.Publisher": getattr(_rclpy, "Publisher", None),
        "rclpy_implementation.Service": getattr(_rclpy, "Service", None),
        "rclpy.node.Node (an instance)": node,
    }
    out = []
    for holder, names in USED.items():
        obj = holders[holder]
        if obj is None and holder.endswith("(an instance)"):
            continue
        out += [f"{holder}.{name}" for name in names if obj is None or not hasattr(obj, name)]
    return out


def installed_version() -> str:
    """The installed rclpy's version ("unknown" where its metadata is absent: a source build)."""
    try:
        return importlib.metadata.version("rclpy")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def rcutils_log() -> Any:
    """rcutils' log call that rclpy's own logger ends in (``rclpy_logging_rcutils_log``): the loop's
    log writes its lines with it (no caller lookup, no logging mutex); None where this rclpy has
    none (the caller keeps rclpy's logger)."""
    return getattr(_rclpy, "rclpy_logging_rcutils_log", None)


def parameter_overrides(node: Node) -> dict[str, Parameter]:
    """The parameter overrides ``node`` was started with (``-p``, params files), by name: rclpy keeps
    them in a private dict it reads when a parameter is declared, and has no public accessor. The
    dict itself is returned: the tables' start-up check replaces an override by its checked value
    (or removes an empty one) before the declaration reads it.

    Raises
    ------
    AttributeError
        Naming this module, if this rclpy keeps them elsewhere.
    """
    try:
        overrides: dict[str, Parameter] = node._parameter_overrides  # noqa: SLF001 - no public accessor
    except AttributeError:
        raise AttributeError(f"{__name__}: this rclpy ({installed_version()}) keeps no Node._parameter_overrides "
                             f"(written against {WRITTEN_AGAINST})") from None
    return overrides


def declared_value(node: Node, name: str) -> Any:
    """A declared parameter's value, None if it is unset (a statically typed parameter with no value:
    a gain not given) or not declared. Public API: rclpy's ``get_parameter`` raises for both."""
    try:
        return node.get_parameter(name).value
    except (ParameterUninitializedException, ParameterNotDeclaredException):
        return None


def declared_parameters(node: Node) -> dict[str, Parameter]:
    """Every parameter ``node`` declared, by name, unset statically typed ones included (rclpy's
    public ``get_parameters_by_prefix`` leaves those out).

    Raises
    ------
    AttributeError
        Naming this module, if this rclpy keeps them elsewhere.
    """
    try:
        declared: dict[str, Parameter] = node._parameters  # noqa: SLF001 - no public accessor with unset ones
    except AttributeError:
        raise AttributeError(f"{__name__}: this rclpy ({installed_version()}) keeps no Node._parameters "
                             f"(written against {WRITTEN_AGAINST})") from None
    return declared


class SubscriptionWaitSet:
    """rcl's wait set (rclpy's private ``WaitSet``) over subscriptions' handles and at most
    ``guards`` guard conditions: the serve loop and the recorder wait on their own subscriptions
    with it, outside any executor (rclpy's public ``WaitSet`` is its executor's own).

    Parameters
    ----------
    subscriptions, guards : int
        How many subscriptions and :class:`WakeUp` guard conditions a :meth:`wait` may be given.
    context : rclpy.context.Context
        The context the subscriptions belong to.
    """

    def __init__(self, subscriptions: int, guards: int, context: Any) -> None:
        self._wait_set = _rclpy.WaitSet(subscriptions, guards, 0, 0, 0, 0, context.handle)

    def wait(self, handles: Any, timeout_ns: int, wake_up: WakeUp | None = None) -> None:
        """Wait until one of the subscriptions' ``handles`` (their rclpy ``Subscription.handle``)
        has a message, ``wake_up`` is triggered, or ``timeout_ns`` has passed."""
        wait_set = self._wait_set
        wait_set.clear_entities()
        for handle in handles:
            wait_set.add_subscription(handle)
        if wake_up is not None:
            wait_set.add_guard_condition(wake_up.guard)
        wait_set.wait(timeout_ns)


class WakeUp:
    """A guard condition of no node (rclpy's private ``GuardCondition`` made from a context's
    handle): a thread that queues a message for the loop wakes the loop's :class:`SubscriptionWaitSet`."""

    def __init__(self, context: Any) -> None:
        self.guard = _rclpy.GuardCondition(context.handle)

    def trigger(self) -> None:
        self.guard.trigger_guard_condition()

    def destroy(self) -> None:
        self.guard.destroy_when_not_in_use()


def take_raw(subscription: Any) -> Any:
    """``take()``: the next serialized message of an rclpy ``subscription`` (created with
    ``raw=True``) and its message info, ``(data, info)``, or None if none waits -- rclpy's private
    ``handle.take_message``, bound once (a C partial: no Python call in the loop's path)."""
    return functools.partial(subscription.handle.take_message, subscription.msg_type, True)


def raw_publisher(publisher: Any) -> Any:
    """``publish(data)``: serialized bytes written by an rclpy ``publisher`` (its private
    ``handle.publish_raw``, under the handle's guard against its destruction meanwhile); raises
    :data:`RCLError` as rclpy's ``publish`` does."""
    handle = publisher.handle
    raw = handle.publish_raw

    def publish(data: bytes) -> None:
        with handle:
            raw(data)

    return publish


def take_request(service: Any) -> tuple[Any, Any] | None:
    """The next waiting ``(request, header)`` of an rclpy ``Service`` no executor spins, None if none
    waits (``header`` is what :meth:`rclpy.service.Service.send_response` takes): what rclpy's
    executor does before it calls a service's callback (``handle.service_take_request``).

    Raises
    ------
    AttributeError
        Naming this module, if this rclpy's service handle takes no request that way.
    """
    try:
        take = service.handle.service_take_request
    except AttributeError:
        raise AttributeError(f"{__name__}: this rclpy ({installed_version()}) has no "
                             f"Service.handle.service_take_request (written against {WRITTEN_AGAINST})") from None
    with service.handle:
        taken = take(service.srv_type.Request)
    if taken is None or taken[1] is None:
        return None
    return taken[0], taken[1]


class _EventsAs:
    """rclpy's ``/parameter_events`` writer of a node: its events name ``node`` (from :attr:`on`)."""

    def __init__(self, publisher: Any, node: str) -> None:
        self.publisher = publisher
        self.node = node
        self.on = False

    def publish(self, event: Any) -> None:
        if self.on:
            event.node = self.node
            self.publisher.publish(event)


def node_announcing_as(base: str, *args: Any, **kwargs: Any) -> Node:
    """An rclpy Node (``Node(*args, **kwargs)``) whose ``/parameter_events`` name the node ``base``,
    silent until :func:`announce`: rclpy's own declarations in ``Node.__init__`` (``use_sim_time``)
    and a stand-in's are ``base``'s, which announced them itself. rclpy has no public way to
    publish a node's parameter events under another name: its private writer is wrapped."""

    class AnnouncingNode(Node):
        @property
        def _parameter_event_publisher(self) -> Any:
            return self._events_as

        @_parameter_event_publisher.setter
        def _parameter_event_publisher(self, publisher: Any) -> None:  # rclpy's writer, then None at destruction
            self._events_as = None if publisher is None else _EventsAs(publisher, base)

    return AnnouncingNode(*args, **kwargs)


def announce(node: Node) -> None:
    """A :func:`node_announcing_as` node's parameter events are published from now on."""
    node._parameter_event_publisher.on = True  # type: ignore[attr-defined]  # noqa: SLF001 - ours, wrapped above


class _SerializedMessage(ctypes.Structure):
    """``rcl_serialized_message_t`` (``rcutils_uint8_array_t``): the bytes, their length, the
    buffer's capacity and an allocator (five pointers; unused by a publish)."""

    _fields_ = [("buffer", ctypes.c_void_p), ("buffer_length", ctypes.c_size_t),
                ("buffer_capacity", ctypes.c_size_t), ("allocator", ctypes.c_void_p * 5)]


class SerializedPublish:
    """``publish(data)``: ``publisher``'s serialized message ``data`` written into the middleware with
    the interpreter lock released -- ``rcl_publish_serialized_message`` and ``rcutils_reset_error``
    from the libraries rclpy loaded (by their sonames, ``RTLD_NOLOAD``: never a second copy), called
    through ctypes on the publisher's handle pointer (rclpy's private ``Publisher.handle.pointer``).
    Returns ``(failed, why)``: 0 and "" when written.

    Raises
    ------
    OSError
        Naming this module, where rcl cannot be called so (the libraries not loaded, or this rclpy's
        handle has no pointer).
    """

    def __init__(self, publisher: Any) -> None:
        try:
            publish = ctypes.CDLL("librcl.so", mode=os.RTLD_NOLOAD).rcl_publish_serialized_message
            reset = ctypes.CDLL("librcutils.so", mode=os.RTLD_NOLOAD).rcutils_reset_error
            self._handle = publisher.handle
            self._pointer = self._handle.pointer
        except (OSError, AttributeError) as exc:
            raise OSError(f"{__name__}: rcl_publish_serialized_message cannot be called through ctypes with this "
                          f"rclpy ({installed_version()}; written against {WRITTEN_AGAINST}): {exc}") from None
        publish.argtypes = [ctypes.c_void_p, ctypes.POINTER(_SerializedMessage), ctypes.c_void_p]
        publish.restype = ctypes.c_int32  # rcl_ret_t
        reset.argtypes, reset.restype = [], None
        self._publish, self._reset_error = publish, reset
        self._message = _SerializedMessage()

    def __call__(self, data: bytes) -> tuple[int, str]:
        message = self._message
        message.buffer = ctypes.cast(ctypes.c_char_p(data), ctypes.c_void_p)
        message.buffer_length = message.buffer_capacity = len(data)
        try:
            with self._handle:  # the publisher is not destroyed while it is written to
                failed = int(self._publish(self._pointer, ctypes.byref(message), None))
        except Exception as exc:  # noqa: BLE001 - the publisher destroyed: never fatal
            return 1, str(exc)
        if failed:
            self._reset_error()
            return failed, f"rcl_publish_serialized_message returned {failed}"
        return 0, ""
