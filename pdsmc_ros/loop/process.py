"""A process's nodes from start to exit: one or several nodes, their parameters checked, the serve
loop (:mod:`.serve`) run lockstep or paced in real time, then their teardown."""

from __future__ import annotations

import faulthandler
import os
import signal
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import (
    InvalidParameterTypeException,
    ParameterException,
)
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

from ..errors import ConfigError, InvalidInputError, PdsmcError
from ..parameters.overrides import check_overrides, warn_unknown_arguments
from ..parameters.params_file import given_value
from ..resources import config_dir
from ..ros import intra
from .inputs import Inputs
from .lifecycle import DRAIN_TIMEOUT_S, EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_OK, arm_teardown_watch
from .realtime_params import LoopReport, loop_reports
from .serve import LocalInputs, NodeGroup, serve_loop


def run_node(
    name: str,
    factory: Callable[[], Any],
    args: Sequence[str] | None,
) -> int:
    """``main()`` body shared by the nodes (ros2/demos style).

    ``factory`` builds the node after ``rclpy.init``; a ConfigError or
    InvalidInputError while building it is one line on stderr and exit 2.
    The node object must offer ``node`` (the rclpy Node), ``done`` and
    ``exit_code`` attributes and may define ``close()``, ``period`` and ``tick()``.
    """
    return run_nodes(name, [factory], args)


PUBLICATION_MODE = "RMW_FASTRTPS_PUBLICATION_MODE"
BUILTIN_TRANSPORTS = "FASTDDS_BUILTIN_TRANSPORTS"
PROFILES_FILE = "FASTRTPS_DEFAULT_PROFILES_FILE"  # the name Fast DDS 2.x reads
DISCOVERY_RANGE = "ROS_AUTOMATIC_DISCOVERY_RANGE"
# settings by which the environment already chooses the transports: left as they are
TRANSPORTS_CHOSEN_BY = (BUILTIN_TRANSPORTS, PROFILES_FILE, "FASTDDS_DEFAULT_PROFILES_FILE")
LOCALHOST_PROFILE = "fastdds_realtime_localhost.xml"  # in config/
# in config/: scripts/run_experiment.sh's profile (leases and heartbeats, no transports): under SUBNET and
# SYSTEM_DEFAULT the built-in transports still apply beside it
OWN_PROFILE = "fastdds_profile.xml"
ALWAYS_REAL_TIME = ("mujoco_driver",)  # nodes that run in real time whatever their parameters


def choose_middleware(node_names: Sequence[str], args: Sequence[str] | None) -> dict[str, str]:
    """Before ``rclpy.init``: a real-time process's middleware settings put in the environment;
    those set (none for a lockstep process, and none the environment already chooses).

    Two ways in which Fast DDS (rmw_fastrtps) makes a writer wait for a reader that has just
    appeared, and through the interpreter lock every thread of the process with it:

    * rmw_fastrtps writes synchronously by default: a write sends in the calling thread, which
      waits while the middleware matches the new reader (``bench/storm``: the control loop
      stood still 13-22 ms when clients subscribed to its commands). Real time writes
      asynchronously (``RMW_FASTRTPS_PUBLICATION_MODE=ASYNCHRONOUS``): the middleware's own
      thread sends.
    * Its shared-memory transport checks a process's port before it first sends to it and, when
      the port's listener has not yet answered, sleeps a third of the port's
      ``healthy_check_timeout_ms`` (1 s by default, set by the port's owner, so by the client)
      while it holds the writer and the participant's send lock (Fast DDS 2.14
      ``SharedMemGlobal::Port::healthy_check``, reached from ``StatefulWriter::matched_reader_add``):
      the 333 ms stand-stills of ``bench/storm`` as clients came and went. Real time sends over
      UDP only, so it never opens a client's port; the other processes keep shared memory among
      themselves. For the discovery ranges SUBNET (Jazzy's default) and SYSTEM_DEFAULT that is
      ``FASTDDS_BUILTIN_TRANSPORTS=UDPv4``. For LOCALHOST rmw_fastrtps always adds a shared-memory
      transport, so the process takes ``config/fastdds_realtime_localhost.xml`` (LOCALHOST's
      discovery, over the loopback only) with the range SYSTEM_DEFAULT, under which rmw_fastrtps
      keeps the profile's transports.

    Transports stay as the environment has them under another middleware (``RMW_IMPLEMENTATION``),
    with discovery OFF, with the deprecated ``ROS_LOCALHOST_ONLY=1``, with LOCALHOST and static
    peers (other hosts too) or ``scripts/run_experiment.sh``'s profile (:data:`OWN_PROFILE`, whose
    leases and heartbeats the real-time profile does not carry), and where the environment already
    chooses them (:data:`TRANSPORTS_CHOSEN_BY`: a profiles file other than :data:`OWN_PROFILE`,
    built-in transports). The process's children (the controller's goal process) inherit what is
    set.

    Lockstep keeps the defaults: asynchronous writes add a thread hand-off to every message of
    its round trips (``bench/lockstep.py``: 24,000 and 20,000 steps a second synchronous,
    18,000 and 12,000 asynchronous).
    """
    argv = list(sys.argv if args is None else args)
    if not any(name in ALWAYS_REAL_TIME or given_value("mode", f"/{name}", argv) == "realtime"
               for name in node_names):
        return {}
    environ = os.environ
    chosen = {} if environ.get(PUBLICATION_MODE) else {PUBLICATION_MODE: "ASYNCHRONOUS"}  # "": rmw's default
    discovery = environ.get(DISCOVERY_RANGE, "")
    try:
        config = config_dir()
    except ConfigError:  # a broken install: the node says so itself
        config = None
    own_profile = config is not None and _same_file(environ.get(PROFILES_FILE, ""), config / OWN_PROFILE)
    fastrtps = (environ.get("RMW_IMPLEMENTATION") or "rmw_fastrtps_cpp") == "rmw_fastrtps_cpp"
    # rcl: ROS_LOCALHOST_ONLY=1 (deprecated) overrides the range; any other value leaves it
    user_choice = [key for key in TRANSPORTS_CHOSEN_BY
                   if environ.get(key) and not (own_profile and key == PROFILES_FILE)]
    if fastrtps and config is not None and environ.get("ROS_LOCALHOST_ONLY") != "1" and not user_choice:
        if discovery == "LOCALHOST":
            # not with static peers (other hosts too), nor in place of run_experiment.sh's profile,
            # whose leases and heartbeats the real-time profile does not carry
            if not environ.get("ROS_STATIC_PEERS") and not own_profile:
                chosen[DISCOVERY_RANGE] = "SYSTEM_DEFAULT"
                chosen[PROFILES_FILE] = str(config / LOCALHOST_PROFILE)
        elif discovery in ("", "SUBNET", "SYSTEM_DEFAULT"):
            chosen[BUILTIN_TRANSPORTS] = "UDPv4"
    environ.update(chosen)
    return chosen


def _same_file(path: str, other: Path) -> bool:
    """Whether ``path`` (an environment variable's value, maybe empty) names the file ``other``."""
    try:
        return bool(path) and os.path.samefile(path, other)
    except OSError:
        return False


def run_nodes(
    name: str,
    factories: Sequence[Callable[[], Any]],
    args: Sequence[str] | None,
    *,
    intra_process: bool = False,
    node_names: Sequence[str] | None = None,
) -> int:
    """Run one or several node wrappers in this process with one executor.

    Several wrappers make the composed mode (the nodes stay separate rclpy
    nodes, as in a component container). They are closed in reverse order of
    creation, so a recorder created first is closed last. ``intra_process``
    hands the loop's messages between them without DDS (:mod:`.intra`).
    """
    choose_middleware([name] if node_names is None else node_names, args)
    # SIGUSR1 prints every thread's stack and the process goes on: how a node that does not stop is
    # looked into (faulthandler's C handler: it answers even when a thread holds the GIL)
    faulthandler.register(signal.SIGUSR1, file=sys.__stderr__, all_threads=True)
    rclpy.init(args=args)
    wrappers: list[Any] = []
    reports: list[LoopReport] = []  # the real-time settings and loop statistics of each loop node
    executor: SingleThreadedExecutor | None = None
    domain = intra.IntraProcess(rclpy.get_default_context()) if intra_process else None
    code = EXIT_OK
    # our handlers from the start: a signal arriving while rclpy builds a node or the executor
    # would otherwise interrupt its __init__ (and rclpy's __del__ of the half-built object
    # prints a traceback); it is noted here and ends the loop as soon as the loop starts
    signalled = _SignalNote()
    _install_signal_handlers(signalled)
    try:
        try:
            intra.activate(domain)
            for factory in factories:
                wrappers.append(factory())
                reports += loop_reports(wrappers[-1])
            check_overrides([w.node for w in wrappers], args)  # undeclared -p: a warning; params files: errors
            if domain is not None:
                domain.bind()
        except (InvalidInputError, ParameterException, InvalidParameterTypeException, ValueError,
                TypeError) as exc:
            warn_unknown_arguments(name, args)
            print(f"{name}: error: {exc}", file=sys.stderr, flush=True)
            code = EXIT_BAD_INPUT  # also what the teardown watch is armed with
            return code
        except PdsmcError as exc:
            warn_unknown_arguments(name, args)
            print(f"{name}: error: {exc}", file=sys.stderr, flush=True)
            code = EXIT_FAILURE
            return code
        finally:
            intra.activate(None)
        group = NodeGroup(wrappers, reports)
        period = group.period
        # The loop's messages go through a hand-driven wait set (Inputs), the rest through
        # the executor between them. Real-time nodes are paced by the loop, not by rclpy
        # timers (they fired 35x too often under this wheel's EventsExecutor and wake
        # late under the default one).
        executor = SingleThreadedExecutor()
        for wrapper in wrappers:
            executor.add_node(wrapper.node)
        if signalled.stopped_by_signal:
            group.done, group.stopped_by_signal = True, signalled.stopped_by_signal
        _install_signal_handlers(group)
        with_inputs = [inputs for w in wrappers for inputs in _inputs_of(w)]
        # the loop's own inputs are taken at every pass; observers' (composed or alone) in batches
        loop_inputs = [item for inputs in with_inputs if not inputs.batch_s for item in inputs.hot]
        observed = [item for inputs in with_inputs if inputs.batch_s for item in inputs.hot]
        observe_every = min((inputs.batch_s for inputs in with_inputs if inputs.batch_s), default=0.0)
        local = LocalInputs(
            [item for inputs in with_inputs if not inputs.batch_s for item in inputs.local],
            [item for inputs in with_inputs if inputs.batch_s for item in inputs.local],
            None if domain is None else domain.guard)
        serve_loop(executor, group, loop_inputs, period, observed, observe_every, local,
                    busy_wait=group.busy_wait, reports=reports)
        code = group.exit_code
        if not group.stopped_by_signal:
            _drain(executor, wrappers)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = max((getattr(w, "exit_code", EXIT_OK) for w in wrappers), default=EXIT_OK)
    finally:
        for wrapper in reversed(wrappers):
            close = getattr(wrapper, "close", None)
            if close is not None:
                close()
        arm_teardown_watch(code)
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)  # before the nodes go (rclpy's order)
        for wrapper in reversed(wrappers):
            for inputs in _inputs_of(wrapper):
                inputs.destroy()
            wrapper.node.destroy_node()
        if domain is not None:
            domain.destroy()
        rclpy.try_shutdown()
    return code


def _inputs_of(wrapper: Any) -> list[Inputs]:
    """A wrapper's ``inputs`` and, if it has them, its ``observed_inputs`` (taken in batches)."""
    return [inputs for inputs in (getattr(wrapper, "inputs", None), getattr(wrapper, "observed_inputs", None))
            if inputs is not None]


def _drain(executor: Any, wrappers: Sequence[Any], timeout: float = DRAIN_TIMEOUT_S) -> None:
    """After the work is done: let subscribers acknowledge the last messages, then linger.

    A reliable sample lost on the way is repaired only after the writer's next
    heartbeat; a node that exits at once never repairs it (a real-time
    trajectory once missed the plant's last state this way). Waits at most
    ``timeout`` in all (a killed subscriber never acknowledges), then serves
    the executor briefly for what needs a callback (parameter events, acks).
    """
    end = time.perf_counter() + timeout
    for wrapper in wrappers:
        for publisher in wrapper.node.publishers:
            left = end - time.perf_counter()
            if left <= 0.0:
                break
            publisher.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))
    end = time.perf_counter() + 0.1
    while rclpy.ok() and time.perf_counter() < end:
        executor.spin_once(timeout_sec=0.02)


class _SignalNote:
    """Where a signal that arrives before the node group exists is noted."""

    done = False
    stopped_by_signal: str | None = None


def _install_signal_handlers(wrapper: Any) -> None:
    """SIGINT/SIGTERM end the spin loop; the node's close() then runs."""

    def handler(signum: int, frame: object) -> None:  # noqa: ARG001
        wrapper.done = True
        wrapper.stopped_by_signal = signal.Signals(signum).name

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
