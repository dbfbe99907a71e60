"""The engine's allocator setting (pdsmc_ros/engine.py keep_freed_memory): a worker that allocates
and frees a run's arrays again and again takes its pages from the heap, not fresh from the kernel."""

from __future__ import annotations

import subprocess
import sys

import pytest

CHILD = """
import dataclasses, resource
from pdsmc_ros.engine import keep_freed_memory
from pdsmc_ros.presets import make_run
from pdsmc_ros.sim import simulate

spec = dataclasses.replace(make_run("parallel_5r", "circle", "pdsmc"), duration_factor=0.2)

def faults_of_runs(count):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(count):
        simulate(spec, check_stability=False)
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before

faults_of_runs(2)  # compiled code loaded, the reference built
default = faults_of_runs(4)
keep_freed_memory()
keep_freed_memory()  # once per process: a second call changes nothing
faults_of_runs(2)  # the heap grows to what a run needs
kept = faults_of_runs(4)
print(default, kept)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_freed_arrays_are_reused_without_page_faults() -> None:
    out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, timeout=300, check=True)
    default, kept = map(int, out.stdout.split()[-2:])
    # four five-bar runs of 10,000 steps: by default their arrays come as fresh pages, faulted in
    assert kept < default / 5, (default, kept)
