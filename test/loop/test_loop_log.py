"""The control loop's log lines: queued by the loop's thread, written by the executor (issue 37)."""

from __future__ import annotations

import threading

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from pdsmc_ros.loop import log as loop_log  # noqa: E402
from pdsmc_ros.loop.log import LOOP_LOG_KEPT, LoopLog, loop_running  # noqa: E402


class Recorded:
    """A stand-in for the node's logger: the lines it was asked to write, with the writing thread."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, str, str]] = []

    def _line(self, level: str, text: str) -> None:
        self.lines.append((level, text, threading.current_thread().name))

    def info(self, text: str) -> None:
        self._line("info", text)

    def warn(self, text: str) -> None:
        self._line("warn", text)

    def error(self, text: str) -> None:
        self._line("error", text)


@pytest.fixture
def node():
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("loop_log_test", context=context, start_parameter_services=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    yield node, executor
    loop_running(False)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)


def test_lines_are_written_by_the_executor_in_order(node) -> None:
    rcl_node, executor = node
    log = LoopLog(rcl_node)
    log.logger = recorded = Recorded()
    loop_running(True)
    log.info("one")
    log.warn("two")
    log.error("three")
    assert recorded.lines == []  # the loop's thread only queued them
    spinner = threading.Thread(target=lambda: executor.spin_once(timeout_sec=5.0), name="spinner")
    spinner.start()
    spinner.join(timeout=10.0)
    assert [(level, text) for level, text, _ in recorded.lines] == [("info", "one"), ("warn", "two"),
                                                                    ("error", "three")]
    assert {thread for _, _, thread in recorded.lines} == {"spinner"}


def test_outside_the_loop_lines_are_written_at_once(node) -> None:
    rcl_node, _ = node
    log = LoopLog(rcl_node)
    log.logger = recorded = Recorded()
    assert not loop_log._looping
    log.warn("at start-up")
    assert recorded.lines[-1][:2] == ("warn", "at start-up")


def test_the_end_of_the_loop_writes_what_is_queued_and_counts_what_was_dropped(node) -> None:
    rcl_node, _ = node
    log = LoopLog(rcl_node)
    log.logger = recorded = Recorded()
    loop_running(True)
    for k in range(LOOP_LOG_KEPT + 3):
        log.info(f"line {k}")
    loop_running(False)
    assert recorded.lines[0][0] == "warn" and "3 log lines of the control loop dropped" in recorded.lines[0][1]
    assert [text for _, text, _ in recorded.lines[1:]] == [f"line {k}" for k in range(3, LOOP_LOG_KEPT + 3)]
    log.info("after the loop")
    assert recorded.lines[-1][1] == "after the loop"


def test_the_node_logger_takes_every_severity_in_turn(node) -> None:
    """rclpy refuses a call site whose severity changes: each severity has its own."""
    rcl_node, executor = node
    log = LoopLog(rcl_node)
    loop_running(True)
    for text in ("a", "b"):
        log.info(text)
        log.warn(text)
        log.error(text)
    executor.spin_once(timeout_sec=5.0)
    assert not log.lines
    loop_running(False)
    log.warn("after")
    log.info("after")


def test_lines_go_to_rcutils_under_the_node_logger_name_and_level(node, capfd: pytest.CaptureFixture[str]) -> None:
    """The executor writes the loop's lines straight to rcutils (rclpy's logger spends 0.4 ms per line
    finding its caller, under the GIL the loop's thread waits for): the same console line, the node
    logger's name and level."""
    rcl_node, _ = node
    log = LoopLog(rcl_node)
    assert isinstance(log.logger, loop_log.RcutilsLines)
    log.warn("a torque limited")
    log.info("a goal accepted")
    rcl_node.get_logger().set_level(rclpy.logging.LoggingSeverity.WARN)
    log.info("below the level")
    log.error("an error")
    err = capfd.readouterr().err
    assert "[WARN]" in err and "[loop_log_test]: a torque limited" in err
    assert "[INFO]" in err and "[loop_log_test]: a goal accepted" in err
    assert "[ERROR]" in err and "[loop_log_test]: an error" in err
    assert "below the level" not in err


def test_a_refused_direct_write_falls_back_to_the_node_logger(node, capfd: pytest.CaptureFixture[str]) -> None:
    """rclpy's direct write is private: should it take other arguments, the line still reaches the log."""
    rcl_node, _ = node
    log = LoopLog(rcl_node)

    def other_signature(*_args: object) -> None:
        raise TypeError("rclpy_logging_rcutils_log(): incompatible function arguments")

    log.logger.write = other_signature
    log.warn("still written")
    log.error("and after")
    err = capfd.readouterr().err
    assert "[loop_log_test]: still written" in err and "[loop_log_test]: and after" in err
