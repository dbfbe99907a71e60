"""The C library from Python: its handle (``mlockall``, :mod:`pdsmc_ros.loop.realtime`) and glibc's
allocator settings (``mallopt``, <malloc.h>), for the processes that tune it.

The Monte Carlo workers (:func:`pdsmc_ros.sim.engine.keep_freed_memory`) and a real-time loop with
its memory locked (:func:`pdsmc_ros.loop.realtime.reserve_memory`) ask glibc to keep freed
memory instead of returning it to the system. Another C library: nothing is set.
"""

from __future__ import annotations

import ctypes
import ctypes.util

M_TRIM_THRESHOLD = -1
"""Free memory at the heap's top beyond this many bytes is returned to the system (-1: never)."""
M_MMAP_THRESHOLD = -3
"""Allocations from this many bytes up get their own ``mmap``'d pages, returned on ``free``."""
M_MMAP_MAX = -4
"""At most this many allocations served by ``mmap`` at once (0: none, all from the heap)."""


def libc() -> ctypes.CDLL:
    """The process's C library, with ``errno`` kept for :func:`ctypes.get_errno`."""
    return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)


def mallopt(param: int, value: int) -> bool:
    """``mallopt(param, value)``; False when the C library is not glibc or refuses."""
    try:
        call = libc().mallopt
    except (OSError, AttributeError):  # another C library: its own policy
        return False
    return bool(call(param, value))
