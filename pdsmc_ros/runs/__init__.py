"""The run: :class:`RunSpec` (everything one closed-loop run needs, as plain data) and the one
builder (:func:`make_run`, :func:`run_from_settings`, :func:`resolve_gains`), whose defaults are the
run table's (:mod:`pdsmc_ros.parameters.run_table`). ROS-free."""

from .builder import RunSpec, make_run, resolve_gains, run_from_settings

__all__ = ["RunSpec", "make_run", "resolve_gains", "run_from_settings"]
