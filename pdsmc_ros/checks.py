"""Whether a value read from YAML, JSON, a ROS parameter or a caller is a number.

In Python ``True`` is an ``int``; nowhere in this package is a bool a number, a gain or a
count, so every check of an input's type goes through these predicates. numpy's scalars
count as numbers. ROS-free.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, TypeGuard

import numpy as np


def is_real(value: object) -> TypeGuard[int | float | np.integer[Any] | np.floating[Any]]:
    """A real number: an ``int`` or ``float`` (numpy's too), not a bool."""
    return not isinstance(value, bool | np.bool_) and isinstance(value, int | float | np.integer | np.floating)


def is_whole(value: object) -> TypeGuard[int | np.integer[Any]]:
    """A whole number: an ``int`` (numpy's too), not a bool."""
    return not isinstance(value, bool | np.bool_) and isinstance(value, int | np.integer)


def are_real(values: object) -> bool:
    """A collection of real numbers (a list, a tuple, an array; not a string). Empty counts."""
    if isinstance(values, str | bytes) or not isinstance(values, Iterable):
        return False
    return all(is_real(v) for v in values)
