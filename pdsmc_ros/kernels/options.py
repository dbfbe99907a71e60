"""numba's compile options of the package's hot kernels.

A kernel of the closed loop allocates nothing (its scratch comes from the caller,
:func:`pdsmc_ros.robots.compiled.workspace`) and returns no array. numba would still count
references to every array it touches: each view a call takes (a row of the RK4 stages, the
reference row of an instant) is an atomic increment and decrement of the array's reference
count, calls into numba's runtime that the compiler cannot remove. In the closed loop those counts
cost more than its arithmetic: ``bench/kernel.py`` measured the serial arm x1.23 and the five-bar
x1.23 of the hand-unrolled loop with them, x1.08 and x1.02 without (docs/PERFORMANCE.md).

:data:`ALLOCATION_FREE` compiles a kernel without numba's runtime (NRT), so without the counts.
numba then refuses, at compile time, a kernel that allocates an array (``np.empty``, ``copy``)
or returns a view it made: the option also holds the kernels to what they promise. Only
functions that return nothing or scalars take it; functions inlined into one
(``inline="always"``) are compiled with their caller's options.

Every other compiled function of the package names its choice too: numba compiles a function that
does not with the options of the first compiled caller that calls it, so a kernel's options would
depend on which caller a process ran first (test/test_kernel_options.py holds every kernel to it).
"""

from __future__ import annotations

from typing import Any, Final

ALLOCATION_FREE: Final[dict[str, Any]] = {"cache": True, "_nrt": False}
"""``@njit(**ALLOCATION_FREE)``: cached, compiled without reference counting (see the module)."""

WITH_RUNTIME: Final[dict[str, Any]] = {"cache": True, "_nrt": True}
"""``@njit(**WITH_RUNTIME)``: cached, with numba's runtime: a kernel that calls back into Python
(``objmode``: the arrays it hands to Python must be boxed as the views they are) or allocates."""
