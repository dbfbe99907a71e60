"""The number predicates every input check uses (pdsmc_ros/checks.py): a bool is never a number."""

from __future__ import annotations

import array

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from pdsmc_ros.checks import are_real, is_real, is_whole


@given(st.one_of(st.integers(), st.floats(allow_nan=True, allow_infinity=True)))
def test_python_numbers_are_real_and_only_integers_whole(value: float) -> None:
    assert is_real(value)
    assert is_whole(value) == isinstance(value, int)


def test_bools_strings_and_containers_are_not_numbers() -> None:
    for value in (True, False, np.bool_(True), "1", b"1", None, [1.0], (1,), {}, 1j):
        assert not is_real(value), value
        assert not is_whole(value), value


def test_numpy_scalars_count() -> None:
    assert is_real(np.float64(0.5)) and is_real(np.float32(0.5)) and is_real(np.int64(3))
    assert is_whole(np.int32(3)) and not is_whole(np.float64(3.0)) and not is_whole(3.0)


def test_collections_of_numbers() -> None:
    assert are_real([1, 2.5]) and are_real((0.0,)) and are_real(np.array([1.0, 2.0]))
    assert are_real(array.array("d", [1.0, 2.0]))  # how rclpy may hand a double-array parameter
    assert are_real([])  # empty: the caller checks the length it needs
    for values in ("12", b"12", [1.0, True], [1.0, "2"], 3.0, None, [[1.0]]):
        assert not are_real(values), values
