"""The engine's allocator setting (pdsmc_ros/sim/engine.py keep_freed_memory): a worker that allocates
and frees a run's arrays again and again takes its pages from the heap, not fresh from the kernel."""

from __future__ import annotations

import subprocess
import sys

import pytest

CHILD = """
import resource
import numpy as np
from pdsmc_ros.sim.engine import keep_freed_memory

def faults_of_runs(count):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(count):
        samples = np.ones((700_000, 6))  # a long UR5 run's samples: 34 MB, above glibc's adaptive 32 MB
        samples.sum()
        del samples
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before

faults_of_runs(2)
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
    # four runs' samples of 34 MB: by default each comes as fresh pages, faulted in. (Four five-bar
    # runs of 10,000 steps were the workload before: since the five-bar's forward position stopped
    # making (N, 2) temporaries, their arrays no longer fault by default, 1,045 -> 1 faults.)
    assert kept < default / 5, (default, kept)
