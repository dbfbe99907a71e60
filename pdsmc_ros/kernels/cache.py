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

The hash is recorded in the directory numba will write to even when that directory does
not exist yet (numba creates it on the first compile): otherwise the first run after a
fresh install leaves no mark, and the second finds the first one's kernels unmarked and
deletes them -- two cold starts instead of one (issue 25).
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent.parent
MARKER_PREFIX = "pdsmc_ros-kernels-"
KERNEL = re.compile(r"^@njit\b", re.MULTILINE)
_done = False


OPTIONS = PACKAGE_DIR / "kernels" / "options.py"
"""The kernels' compile options: a change there changes every kernel, and no kernel's file."""


def kernel_sources() -> list[Path]:
    """The package's source files that define numba kernels, and their compile options."""
    return sorted(path for path in PACKAGE_DIR.rglob("*.py")
                  if path == OPTIONS or KERNEL.search(path.read_text(errors="replace")))


def digest(sources: list[Path]) -> str:
    h = hashlib.sha256()
    for path in sources:
        h.update(str(path.relative_to(PACKAGE_DIR)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _probe() -> None:
    """A stand-in function for numba's cache locators (they read only its first line number)."""


def numba_cache_dir(source: Path) -> Path | None:
    """The directory numba caches ``source``'s kernels in, created as numba creates it.

    numba tries its locators in order -- ``NUMBA_CACHE_DIR`` (per-directory subfolders), a
    writable ``__pycache__`` beside the file, the user-wide cache -- and takes the first whose
    directory it can create and write to; asking them the same question gives the same answer.
    ``None`` when numba could not cache this file at all. (numba's ``NUMBA_CACHE_LOCATOR_CLASSES``
    override is not followed: with it the refresh marks the default location, not the override's.)
    """
    from numba.core import caching

    # numba's own ordered list (CacheImpl; _CacheImpl in older releases), else its three
    # file-backed locators in the order numba has always tried them
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    locator_classes = getattr(impl, "_locator_classes", None) or [
        getattr(caching, name) for name in ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator")
        if hasattr(caching, name)]
    for locator_class in locator_classes:
        locator = locator_class.from_function(_probe, str(source))
        if locator is not None:
            return Path(locator.get_cache_path())
    return None


def cache_dirs(sources: list[Path]) -> set[Path]:
    """Where numba keeps these files' kernels (existing or created now, see :func:`numba_cache_dir`)."""
    return {directory for directory in map(numba_cache_dir, sources) if directory is not None}


def refresh() -> None:
    """Remove the package's cached kernels if they were built from other sources (once per process)."""
    global _done  # noqa: PLW0603 - once per process
    if _done:
        return
    _done = True
    try:
        sources = kernel_sources()
        marker = MARKER_PREFIX + digest(sources)
        directories = cache_dirs(sources)
    except OSError:
        # sources unreadable: nothing to compare against, leave the cache to numba
        return
    stems = {path.stem for path in sources}
    for directory in directories:
        try:
            directory.mkdir(parents=True, exist_ok=True)
            if (directory / marker).exists():
                continue
            for entry in directory.iterdir():
                stale_kernel = entry.suffix in (".nbi", ".nbc") and entry.name.split(".", 1)[0] in stems
                if stale_kernel or entry.name.startswith(MARKER_PREFIX):
                    entry.unlink(missing_ok=True)
            (directory / marker).touch()
        except OSError:
            # a read-only directory: numba cannot write its cache there either, nothing is stale
            continue
