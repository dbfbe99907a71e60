"""The stability check of a gain change in a process of its own (controller/sidecar/gain_check.py).

The child's answers must be the in-process check's, word for word; a child that dies or hangs is
a refusal with the reason and is replaced; closing ends it. ROS-free.
"""

from __future__ import annotations

import dataclasses
import os
import signal
import time

import pytest

from pdsmc_ros.control import Gains
from pdsmc_ros.control.stability import check_rate
from pdsmc_ros.controller.sidecar.gain_check import CheckProcess, checked
from pdsmc_ros.errors import ConfigError, PdsmcError
from pdsmc_ros.runs.builder import make_run

STABILITY = {"mode": "realtime", "delay_periods": 0, "margin": None, "entry": "node"}


@pytest.fixture(scope="module")
def spec():  # noqa: ANN201
    return make_run("ur5", "circle", "pd", rate=1000.0)  # the shipped UR5 gains: stable at 1 kHz in real time


def in_process_reason(spec) -> str | None:  # noqa: ANN001
    reference = spec.reference()
    try:
        checked(lambda s: check_rate(s, reference, **STABILITY), spec)
    except PdsmcError as exc:
        return str(exc)
    return None


def with_gains(spec, **values: list[float]):  # noqa: ANN001, ANN201
    return dataclasses.replace(spec, gains=Gains.from_mapping({**spec.gains.as_dict(), **values}, 6, spec.controller))


@pytest.mark.timeout(120)
def test_the_child_answers_as_the_in_process_check(spec) -> None:  # noqa: ANN001
    process = CheckProcess(spec, STABILITY)
    try:
        cases = [spec, with_gains(spec, kp=[1e6] * 6), with_gains(spec, kd=[1e308] * 6)]
        reasons = [in_process_reason(case) for case in cases]
        assert reasons[0] is None and reasons[1] and reasons[2]  # stable, unstable, too large to analyse
        for case, reason in zip(cases, reasons):
            if reason is None:
                process(case)
            else:
                with pytest.raises(ConfigError) as raised:
                    process(case)
                assert str(raised.value) == reason
    finally:
        process.close()
    assert process.process is None


@pytest.mark.timeout(120)
def test_a_dead_child_is_a_refusal_and_is_replaced(spec) -> None:  # noqa: ANN001
    process = CheckProcess(spec, STABILITY)
    try:
        process(spec)
        first = process.process
        assert first is not None
        os.kill(first.pid, signal.SIGKILL)
        first.wait(timeout=10)
        process(spec)  # a child found dead before a check is started again
        assert process.process is not None and process.process.pid != first.pid
    finally:
        process.close()


@pytest.mark.timeout(120)
def test_a_child_that_does_not_answer_in_time_is_a_refusal_naming_the_gains(spec) -> None:  # noqa: ANN001
    process = CheckProcess(spec, STABILITY)
    try:
        process(spec)
        child = process.process
        assert child is not None
        process.timeout_s = 1e-6  # no check answers within a microsecond
        with pytest.raises(ConfigError, match=r"^gains .* refused: the stability check process failed "
                                              r"\(TimeoutError: no answer in 1e-06 s\); a new one is starting$"):
            process(spec)
        assert child.poll() is not None  # killed
        process.timeout_s = 30.0
        process(spec)
    finally:
        process.close()


@pytest.mark.timeout(120)
def test_a_stopped_child_is_a_refusal_at_once_and_is_replaced(spec) -> None:  # noqa: ANN001
    """SIGSTOP: alive, never answering. The set is refused as soon as the stop is seen (not after the
    30 s timeout), the child killed and a new one started at once; the next change is checked."""
    process = CheckProcess(spec, STABILITY)
    try:
        process(spec)
        child = process.process
        assert child is not None
        os.kill(child.pid, signal.SIGSTOP)
        began = time.monotonic()
        with pytest.raises(ConfigError, match=r"^gains .* refused: the stability check process failed "
                                              r"\(TimeoutError: the process is stopped \(SIGSTOP\): it would not "
                                              r"answer\); a new one is starting$"):
            process(spec)
        refused_after = time.monotonic() - began
        assert child.poll() is not None  # killed
        assert process.process is not None and process.process.pid != child.pid  # replaced before the next set
        print(f"a stopped gain check refused after {refused_after:.2f} s")
        assert refused_after < 2.0, refused_after
        process(spec)
    finally:
        process.close()


def test_timeout_must_be_positive(spec) -> None:  # noqa: ANN001
    with pytest.raises(ValueError, match="timeout_s must be > 0"):
        CheckProcess(spec, STABILITY, timeout_s=0.0)
