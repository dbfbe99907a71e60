"""Control steps and header stamps: step ``k`` is sim time ``k / rate``, in one place.

The plant stamps its states with the step's time, the trajectory its references,
the controller reads the step back, and the bag reader does the same for whole
topics; all of them call these functions.
"""

from __future__ import annotations

from . import cdr


def step_stamp(step: int, rate: float) -> tuple[int, int]:
    """Header stamp ``(sec, nanosec)`` of control step ``step`` (time ``step / rate``)."""
    return divmod(round(step * 1e9 / rate), 1_000_000_000)  # round() of a float is an int


def stamp_step(sec: int, nanosec: int, rate: float) -> int:
    """Control step of a header stamp (the inverse of :func:`step_stamp`)."""
    return round((sec + nanosec * 1e-9) * rate)


def header_step(data: bytes, rate: float) -> int:
    """Control step of a CDR message that starts with ``std_msgs/Header``."""
    return stamp_step(*cdr.decode_stamp(data), rate)


def effort_step(data: bytes) -> int:
    """Control step of an effort command: ``layout.data_offset`` of its CDR
    ``std_msgs/Float64MultiArray`` (no dimensions)."""
    return cdr.float64_multi_array_offset(data)
