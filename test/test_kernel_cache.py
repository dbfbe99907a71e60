"""The numba kernel cache after a fresh install (issue 25, item 4): the first command (make
setup's precompile) compiles, every later one loads what it compiled -- other laws' runs too.

The refresh (pdsmc_ros.kernels.cache) used to record its marker only in cache directories that
already existed; numba creates them on the first compile, so the second command found the
first one's kernels unmarked, deleted them and compiled again.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT

from pdsmc_ros.kernels import cache as kernel_cache

COMMAND = (sys.executable, "-m", "pdsmc_ros.cli", "simulate", "--robot", "serial_3r", "--contour", "circle",
           "--controller", "pdsmc")


def kernel_files(cache: Path) -> dict[Path, tuple[int, int, str]]:
    """Every cached kernel file: (inode, modification time in ns, SHA-256 of its bytes)."""
    files = {}
    for path in sorted(cache.rglob("*")):
        if path.suffix in (".nbi", ".nbc"):
            st = path.stat()
            files[path] = (st.st_ino, st.st_mtime_ns, hashlib.sha256(path.read_bytes()).hexdigest())
    return files


def run(cache: Path, command: tuple[str, ...] | list[str] = COMMAND) -> str:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), NUMBA_DEBUG_CACHE="1")
    proc = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return proc.stdout


def test_refresh_marks_directories_numba_has_not_created_yet(tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    from numba.core import caching, config

    cache = tmp_path / "numba-cache"
    monkeypatch.setattr(config, "CACHE_DIR", str(cache))
    monkeypatch.setattr(kernel_cache, "_done", False)
    sources = kernel_cache.kernel_sources()
    kernel_cache.refresh()
    marker = kernel_cache.MARKER_PREFIX + kernel_cache.digest(sources)
    # where numba itself will write each file's kernels
    expected = {cache / caching.UserProvidedCacheLocator.get_suitable_cache_subpath(str(p)) for p in sources}
    assert kernel_cache.cache_dirs(sources) == expected
    for directory in expected:
        assert (directory / marker).is_file(), f"no marker in {directory}"


@pytest.mark.timeout(2400)
def test_after_the_first_command_every_command_loads_its_kernels_without_compiling(tmp_path: Path) -> None:
    cache = tmp_path / "numba-cache"  # empty, as after an install
    # the first command: make setup's precompile (of one robot, for time)
    first = run(cache, [sys.executable, "-m", "pdsmc_ros.kernels.precompile", "--robots", "serial_3r"])
    assert "[cache] data saved" in first  # it compiled and wrote its kernels
    compiled = kernel_files(cache)
    assert compiled, f"numba cached nothing in {cache}"
    # the thesis's law, then laws other than the precompile's runs' (theirs compiled through a
    # controller's entry point), each a new process
    for command in (COMMAND, [*COMMAND[:-1], "sta", "--json"], [*COMMAND[:-1], "ismc"]):
        out = run(cache, command)
        saved = [line for line in out.splitlines() if "saved" in line and line.startswith("[cache]")]
        assert not saved, f"{' '.join(command[2:])} compiled again: " + "; ".join(saved[:5])
        assert "[cache] data loaded" in out
        assert kernel_files(cache) == compiled, f"{' '.join(command[2:])} rewrote or removed cached kernels"
