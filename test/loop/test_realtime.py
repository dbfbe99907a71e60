"""Real-time settings (ROS-free part): applied when allowed, read back from the kernel; refused
settings give one warning with the fix and the caller runs on; the loop statistics and the
garbage-collector policy.

Settings are applied in a child process (a SCHED_FIFO or memory-locked pytest would outlive
the test); the child runs a few lines and exits, so no FIFO thread is left behind.
"""

from __future__ import annotations

import gc
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pdsmc_ros.bag.loop_statistics import parse_values
from pdsmc_ros.errors import ConfigError
from pdsmc_ros.loop.realtime import (
    BUSY_WAIT_S,
    FIFO_BUSY_SHARE,
    FIFO_BUSY_WAIT_S,
    FIFO_COMPOSED_BUSY_WAIT_S,
    Collector,
    RealtimeSettings,
    busy_wait_for,
)
from pdsmc_ros.loop.statistics import LoopStatistics
from pdsmc_ros.parameters.tables import AUTO_BUSY_WAIT

ROOT = Path(__file__).resolve().parent.parent.parent

CHILD = """
import json, os, subprocess, sys
from pdsmc_ros.loop.realtime import RealtimeSettings, apply, locked_kib, policy_of, restore, scheduler_of_thread
applied = apply(RealtimeSettings(thread_priority=10, cpu_affinity=(0,), lock_memory=True))
policy, priority = scheduler_of_thread()
child = subprocess.run([sys.executable, "-c", "import os; print(os.sched_getscheduler(0))"], capture_output=True,
                       text=True, check=True).stdout
read = {"policy": policy, "priority": priority, "affinity": sorted(os.sched_getaffinity(0)),
        "getscheduler_fifo": policy_of(0) == os.SCHED_FIFO, "vmlck_kib": locked_kib(),
        "reset_on_fork": bool(os.sched_getscheduler(0) & os.SCHED_RESET_ON_FORK),
        "child_policy": int(child), "warning": applied.warning}
restore(applied)
read["after_policy"] = scheduler_of_thread()[0]
read["after_vmlck_kib"] = locked_kib()
print(json.dumps(read))
"""


def run_child(prefix: list[str] | None = None) -> dict:
    proc = subprocess.run([*(prefix or []), sys.executable, "-c", CHILD], cwd=ROOT, capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def privileged() -> bool:
    """Whether this machine lets a child set SCHED_FIFO and lock its memory (root here)."""
    probe = "import os; os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))"
    return subprocess.run([sys.executable, "-c", probe], capture_output=True, timeout=30).returncode == 0


def test_settings_are_applied_and_read_back_from_the_kernel() -> None:
    if not privileged():
        pytest.skip("this user may not set SCHED_FIFO (the refusal test covers it)")
    read = run_child()
    assert read["policy"] == "SCHED_FIFO" and read["priority"] == 10 and read["getscheduler_fifo"]
    # a process the loop's thread starts runs at normal scheduling (the gain check's)
    assert read["reset_on_fork"] and read["child_policy"] == os.SCHED_OTHER
    assert read["affinity"] == [0]
    assert read["vmlck_kib"] > 0  # /proc/self/status VmLck: the pages are locked
    assert read["warning"] == ""
    assert read["after_policy"] == "SCHED_OTHER" and read["after_vmlck_kib"] == 0


FAULTS_CHILD = """
import json, sys
import numpy as np
from pdsmc_ros.loop import realtime
if sys.argv[1] == "none":
    realtime.reserve_memory = lambda: 0  # what apply() did before it reserved
applied = realtime.apply(realtime.RealtimeSettings(lock_memory=True))
before = realtime.minor_faults()
objects = [(float(i), i) for i in range(100_000)]  # about 10 MiB of small objects
arrays = [np.ones(100_000) for _ in range(10)]  # 10 x 800 kB: above glibc's default mmap threshold
del objects, arrays
print(json.dumps({"faults": realtime.minor_faults() - before, "reserved": applied.reserved,
                  "summary": applied.summary()}))
"""


def faults_after_locking(reserve: str) -> dict:
    proc = subprocess.run([sys.executable, "-c", FAULTS_CHILD, reserve], cwd=ROOT, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_a_memory_locked_loop_allocates_from_reserved_memory_without_page_faults() -> None:
    """With MCL_FUTURE every new mapping is faulted in when made: the loop's later objects and arrays
    come from memory reserved at start-up instead (issue 26: no page faults after warm-up)."""
    if not privileged():
        pytest.skip("this user may not lock its memory (the refusal test covers it)")
    reserved = faults_after_locking("default")
    assert reserved["reserved"] >= 40 << 20 and "MiB reserved" in reserved["summary"]
    assert reserved["faults"] == 0
    unreserved = faults_after_locking("none")
    assert unreserved["faults"] > 1000  # the same allocations, each new arena and array faulted in


def test_refused_settings_warn_once_with_the_fix_and_run_on() -> None:
    setpriv = shutil.which("setpriv")
    if setpriv is None or not privileged():
        pytest.skip("needs setpriv and a privileged user to drop the capabilities from")
    # the capabilities dropped and the limits of an ordinary user: both settings are refused
    read = run_child([setpriv, "--bounding-set=-sys_nice,-ipc_lock", "prlimit", "--rtprio=0", "--memlock=8388608",
                      "--"])
    assert read["policy"] == "SCHED_OTHER" and read["vmlck_kib"] == 0
    assert read["affinity"] == [0]  # what is allowed still holds
    warning = read["warning"]
    assert warning.count("real time: running on without") == 1  # one warning for both refusals
    assert "SCHED_FIFO priority 10" in warning and "rtprio" in warning and "CAP_SYS_NICE" in warning
    assert "lock_memory" in warning and "memlock" in warning and "CAP_IPC_LOCK" in warning
    assert "/etc/security/limits.conf" in warning


def test_bad_settings_are_refused_with_what_is_allowed() -> None:
    with pytest.raises(ConfigError, match=r"thread_priority must be a whole number in \[0, 99\]"):
        RealtimeSettings(thread_priority=100).validated()
    with pytest.raises(ConfigError, match=r"cpu_affinity must list cores in \[0, "):
        RealtimeSettings(cpu_affinity=(4096,)).validated()
    assert RealtimeSettings.for_mode("realtime") == RealtimeSettings(50, (), True)
    assert RealtimeSettings.for_mode("lockstep") == RealtimeSettings(0, (), False)
    merged = RealtimeSettings.merged([RealtimeSettings(10, (1,), False), RealtimeSettings(50, (0,), True)])
    assert merged == RealtimeSettings(50, (0, 1), True)


def test_statistics_count_a_stalled_period() -> None:
    stats = LoopStatistics(0.001, warm_up=2)
    start = 100.0
    for k in range(5):  # on time
        stats.record(start + k * 0.001, 2e-6, start + k * 0.001 + 1e-4)
    stats.page_faults(40)  # warm-up over: faults counted from here
    stats.record(start + 0.0500, 0.0450, start + 0.0501)  # a stall: 45 ms late
    stats.record(start + 0.0510, 0.0, start + 0.0511)
    stats.page_faults(43)
    v = parse_values(stats.values())
    assert v["ticks"] == 5 and v["missed"] == 1  # the 2 warm-up ticks are not counted
    assert v["late_max_us"] == pytest.approx(45000.0)
    assert v["period_worst_us"] == pytest.approx(46000.0, abs=0.2)
    assert v["minor_faults"] == 3


def test_collector_keeps_collection_out_of_the_loop() -> None:
    collector = Collector(young_at=100)
    try:
        collector.start()
        assert not gc.isenabled()
        assert gc.get_freeze_count() > 0
        assert not collector.idle() or gc.get_count()[0] == 0
        for _ in range(500):  # reference cycles: only a collection frees them
            cycle: list = []
            cycle.append(cycle)
        del cycle
        assert collector.idle() and collector.collections == 1
        assert gc.get_count()[0] < 100
    finally:
        collector.stop()
    assert gc.isenabled() and gc.get_freeze_count() == 0


def test_the_last_statistics_of_each_node_are_read_back_from_a_bag(tmp_path: Path) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from pdsmc_ros.bag.loop_statistics import bag_loop_statistics, format_loop_statistics, status_name

    store = get_typestore(Stores.ROS2_JAZZY)
    Array, Status, KeyValue = (store.types[f"diagnostic_msgs/msg/{n}"] for n in ("DiagnosticArray",
                                                                                  "DiagnosticStatus", "KeyValue"))
    Header, Time = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]

    def array(name: str, missed: int) -> object:
        stats = LoopStatistics(0.001, warm_up=0)
        for k in range(10):
            stats.record(k * 0.001, 0.002 if k < missed else 0.0, k * 0.001 + 1e-4)
        values = [KeyValue(key=k, value=v) for k, v in stats.values().items()]
        return Array(header=Header(stamp=Time(sec=0, nanosec=0), frame_id=""),
                     status=[Status(level=0, name=name, message="", hardware_id="", values=values)])

    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", typestore=store)
        for t, (name, missed) in enumerate([(status_name("controller"), 1), (status_name("plant"), 0),
                                            (status_name("controller"), 3), ("plant: other status", 9)]):
            writer.write(conn, t + 1, store.serialize_cdr(array(name, missed), conn.msgtype))
    stats = bag_loop_statistics(bag)
    assert set(stats) == {"controller", "plant"}
    assert stats["controller"]["missed"] == 3 and stats["controller"]["ticks"] == 10  # the last one
    assert stats["plant"]["missed"] == 0
    lines = format_loop_statistics("run", stats)
    assert lines[0].startswith("run: controller loop: 10 ticks, missed 3 (30.000 %)")


def test_the_automatic_spin_follows_the_scheduling_and_a_given_one_is_kept() -> None:
    auto = AUTO_BUSY_WAIT
    assert busy_wait_for(auto, fifo=False, loops=3, period=1e-3) == BUSY_WAIT_S
    assert busy_wait_for(auto, fifo=True, loops=1, period=1e-3) == FIFO_BUSY_WAIT_S
    assert busy_wait_for(auto, fifo=True, loops=3, period=1e-3) == FIFO_COMPOSED_BUSY_WAIT_S
    assert busy_wait_for(auto, fifo=True, loops=3, period=4e-4) == FIFO_BUSY_SHARE * 4e-4
    assert busy_wait_for(auto, fifo=True, loops=1, period=None) == FIFO_BUSY_WAIT_S  # lockstep: not paced
    # a value given is the user's, also one equal to an automatic choice; FIFO caps it at its share
    for given in (0.0, BUSY_WAIT_S, FIFO_BUSY_WAIT_S):
        assert busy_wait_for(given, fifo=True, loops=1, period=1e-3) == given
    assert busy_wait_for(1e-3, fifo=False, loops=1, period=1e-3) == 1e-3
    assert busy_wait_for(1e-3, fifo=True, loops=1, period=1e-3) == FIFO_BUSY_SHARE * 1e-3
