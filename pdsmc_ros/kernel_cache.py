"""Keep numba's on-disk cache of the package's kernels consistent with their sources.

numba checks a cached kernel against its own source file only (its modification time
and size), not against the kernels it calls. After an upgrade that changes, say, the
robot dispatch in ``robots/compiled.py`` but not ``sim/loop.py``, the cached closed
loop would still call the old dispatch -- silently wrong numbers, or a division by
zero for a robot the old dispatch does not know. :func:`refresh` hashes every source
file with a kernel and, when the hash is not the one the cache was built from,
removes the package's cached kernels (they recompile on first use) and records the
new hash. It runs once, when :mod:`pdsmc_ros.robots` is imported, before any kernel
is called.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
MARKER_PREFIX = "pdsmc_ros-kernels-"
KERNEL = re.compile(r"^@njit\b", re.MULTILINE)
_done = False


def kernel_sources() -> list[Path]:
    """The package's source files that define numba kernels."""
    return sorted(path for path in PACKAGE_DIR.rglob("*.py") if KERNEL.search(path.read_text(errors="replace")))


def digest(sources: list[Path]) -> str:
    h = hashlib.sha256()
    for path in sources:
        h.update(str(path.relative_to(PACKAGE_DIR)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def cache_dirs(sources: list[Path]) -> set[Path]:
    """Where numba keeps these files' kernels: ``__pycache__`` beside them, or under
    ``NUMBA_CACHE_DIR`` in numba's per-directory subfolders."""
    dirs = {path.parent / "__pycache__" for path in sources}
    from numba.core import caching, config

    cache_dir = getattr(config, "CACHE_DIR", "")
    # numba names the class UserProvidedCacheLocator (older releases: with a leading underscore)
    locator = getattr(caching, "UserProvidedCacheLocator", None) or getattr(caching, "_UserProvidedCacheLocator", None)
    if cache_dir and locator is not None:
        dirs |= {Path(cache_dir) / locator.get_suitable_cache_subpath(str(path)) for path in sources}
    return dirs


def refresh() -> None:
    """Remove the package's cached kernels if they were built from other sources (once per process)."""
    global _done  # noqa: PLW0603 - once per process
    if _done:
        return
    _done = True
    try:
        sources = kernel_sources()
        marker = MARKER_PREFIX + digest(sources)
        stems = {path.stem for path in sources}
        for directory in cache_dirs(sources):
            if not directory.is_dir() or (directory / marker).exists():
                continue
            for entry in directory.iterdir():
                stale_kernel = entry.suffix in (".nbi", ".nbc") and entry.name.split(".", 1)[0] in stems
                if stale_kernel or entry.name.startswith(MARKER_PREFIX):
                    entry.unlink(missing_ok=True)
            (directory / marker).touch()
    except OSError:
        # a read-only install: numba cannot write its cache there either, nothing is stale
        return
