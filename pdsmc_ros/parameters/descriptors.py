"""Numbers the nodes derive from their parameters, and the descriptor of a parameter declared by
hand (the tables of :mod:`pdsmc_ros.parameters` derive theirs: prefer a table)."""

from __future__ import annotations

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor


def descriptor(
    description: str, *, lo: float | None = None, hi: float | None = None, constraints: str = ""
) -> ParameterDescriptor:
    """A dynamically typed descriptor (the declaring code checks the type) with an optional range."""
    desc = ParameterDescriptor(description=description, additional_constraints=constraints, dynamic_typing=True)
    if lo is not None and hi is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]
    return desc


def decimation(rate: float, target: float) -> int:
    """Publish every ``decimation`` steps so a ``rate`` Hz loop emits at most ``target`` Hz."""
    return max(1, int(round(rate / target)))
