"""Control steps and header stamps (pdsmc_ros.bag.stamps) and malformed live messages."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pdsmc_ros.bag import cdr
from pdsmc_ros.bag.stamps import effort_step, header_step, stamp_step, step_stamp
from pdsmc_ros.errors import BagError, CdrError


@given(st.integers(0, 10_000_000), st.sampled_from([100.0, 250.0, 1000.0, 5000.0, 10000.0, 12345.0]))
def test_a_step_survives_its_stamp(step: int, rate: float) -> None:
    sec, nanosec = step_stamp(step, rate)
    assert 0 <= nanosec < 1_000_000_000
    assert stamp_step(sec, nanosec, rate) == step


def test_steps_of_encoded_messages() -> None:
    sec, nanosec = step_stamp(4321, 10000.0)
    state = cdr.encode_joint_state(sec, nanosec, ["joint1"], [0.1], [0.2], [0.3])
    assert header_step(state, 10000.0) == 4321
    assert effort_step(cdr.encode_float64_multi_array([1.0, 2.0], 77)) == 77


@pytest.mark.parametrize(
    "data", [b"", b"\x00\x01\x00\x00", b"\x00\x01\x00\x00\x01\x00", b"\x01\x00\x00\x00" + bytes(12)]
)
def test_a_malformed_live_message_is_a_cdr_error_not_an_io_error(data: bytes) -> None:
    """A node catches CdrError (a ValueError): malformed content is not an I/O failure (BagError)."""
    assert issubclass(CdrError, ValueError) and not issubclass(CdrError, OSError)
    with pytest.raises(CdrError) as caught:
        header_step(data, 1000.0)
    assert not isinstance(caught.value, BagError)
    with pytest.raises(CdrError):
        effort_step(data)
