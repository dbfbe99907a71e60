"""``pdsmc rt-check``: what real time needs on this machine, checked, then a paced loop measured.

Checks (each failing one with its fix): the kernel (PREEMPT_RT or not), whether this user may
run a thread at ``SCHED_FIFO`` (``rtprio`` limit, ``CAP_SYS_NICE``, the kernel's real-time
throttling) and lock memory (``memlock`` limit, ``CAP_IPC_LOCK``), the CPU frequency
governor, isolated cores, and the loop's page faults after warm-up. Then it runs a loop at
``--rate`` for ``--duration`` seconds paced as the nodes' serve loop paces its ticks (sleep
until ``--busy-wait`` before the deadline, spin the rest) with the nodes' real-time settings
(:mod:`pdsmc_ros.loop.realtime`: ``--priority``, ``--cpu``, ``--no-lock-memory``) and
prints the histogram of how late each tick started (p50, p99, p99.9, max) and the periods
missed. ROS 2's real-time demo asks for no page fault after start-up and a mean latency
under 3 % of the period. Exit 0 when it ran, 2 on bad input; never needs ROS.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import resource
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..arguments import EXIT_USAGE, OneLineParser
from ..errors import InvalidInputError
from ..parameters.tables import AUTO_BUSY_WAIT, DEFAULT_PRIORITY, MAX_PRIORITY
from .realtime import (
    AFFINITY_FIX,
    CAP_IPC_LOCK,
    CAP_SYS_NICE,
    FIFO_FIX,
    MEMLOCK_FIX,
    Collector,
    RealtimeSettings,
    apply,
    busy_wait_for,
    capability,
    minor_faults,
    restore,
)
from .statistics import LoopStatistics

BUCKETS_US = (10, 20, 50, 100, 200, 500, 1000)
WARM_UP_S = 1.0
MAX_DURATION_S = 3600.0
Check = tuple[str, bool, str, str]  # name, passed, what was found, the fix if not passed


def add_parser(sub: argparse._SubParsersAction, commands: dict) -> None:  # type: ignore[type-arg]
    """Register ``rt-check`` on ``pdsmc``'s subcommands."""
    add_arguments(sub.add_parser("rt-check", help="check this machine for real time and measure a 1 kHz loop"))
    commands["rt-check"] = run


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``pdsmc rt-check`` and ``python -m pdsmc_ros.loop.rt_check``."""
    p.add_argument("--duration", type=float, default=10.0, help="seconds of the measured loop (default 10)")
    p.add_argument("--rate", type=float, default=1000.0, help="loop rate in Hz (default 1000)")
    p.add_argument("--priority", type=int, default=DEFAULT_PRIORITY,
                   help=f"SCHED_FIFO priority of the loop, 0-{MAX_PRIORITY} (0: normal; default {DEFAULT_PRIORITY}, "
                        "the nodes' thread_priority in real time)")
    p.add_argument("--cpu", default="", help="cores the loop may run on, e.g. 1 or 0,1 (the nodes' cpu_affinity)")
    p.add_argument("--no-lock-memory", action="store_true", help="do not lock memory (the nodes' lock_memory:=false)")
    p.add_argument("--busy-wait", type=float, default=None,
                   help="seconds before each tick spent spinning instead of sleeping (the nodes' busy_wait; "
                        "default as the nodes: 0.00005 at SCHED_FIFO, 0.0002 at normal priority)")


def settings_from(args: argparse.Namespace) -> tuple[RealtimeSettings, float, float, float]:
    """The loop's settings, period, duration and busy-wait; InvalidInputError naming a bad one."""
    if not (np.isfinite(args.duration) and 0.1 <= args.duration <= MAX_DURATION_S):
        raise InvalidInputError(f"--duration must be seconds in [0.1, {MAX_DURATION_S:g}], got {args.duration:g}")
    if not (np.isfinite(args.rate) and 1.0 <= args.rate <= 20000.0):
        raise InvalidInputError(f"--rate must be Hz in [1, 20000], got {args.rate:g}")
    period = 1.0 / args.rate
    if args.busy_wait is None:  # as a loop node's serve loop chooses at this priority
        args.busy_wait = busy_wait_for(AUTO_BUSY_WAIT, fifo=args.priority > 0, loops=1, period=period)
    if not (np.isfinite(args.busy_wait) and 0.0 <= args.busy_wait <= period):
        raise InvalidInputError(f"--busy-wait must be seconds in [0, {period:g}] (one period), got {args.busy_wait:g}")
    try:
        cores = tuple(int(c) for c in args.cpu.split(",") if c.strip()) if args.cpu.strip() else ()
    except ValueError:
        raise InvalidInputError(f"--cpu takes core numbers separated by commas, e.g. 1 or 0,1; got {args.cpu!r}") \
            from None
    try:
        settings = RealtimeSettings(args.priority, cores, not args.no_lock_memory).validated()
    except InvalidInputError as exc:
        message = str(exc).replace("thread_priority", "--priority").replace("cpu_affinity", "--cpu")
        raise InvalidInputError(message) from None
    return settings, period, args.duration, args.busy_wait


def _read(path: str) -> str:
    try:
        return Path(path).read_text().strip()
    except OSError:
        return ""


def preemption(version: str) -> str:
    """How the running kernel preempts itself: the active mode of a ``PREEMPT_DYNAMIC`` kernel
    (``/sys/kernel/debug/sched/preempt``, the ``preempt=`` boot parameter, or the boot log's
    ``Dynamic Preempt:`` line, the first that can be read), else what ``uname -v`` says. Under
    ``none`` a task inside a system call keeps its CPU until the call returns, so a real-time
    thread waits for other processes' kernel work (``docs/PERFORMANCE.md``, the machine)."""
    if "PREEMPT_RT" in version:
        return "rt"
    if "PREEMPT_DYNAMIC" in version:
        active = re.search(r"\((\w+)\)", _read("/sys/kernel/debug/sched/preempt"))
        if active:
            return active.group(1)
        boot = re.search(r"(?:^|\s)preempt=(\w+)", _read("/proc/cmdline"))
        if boot:
            return boot.group(1)
        logged = _boot_log_line("Dynamic Preempt: ")
        return logged or "dynamic (mode unknown: /sys/kernel/debug/sched/preempt and the boot log are not readable)"
    return "full" if re.search(r"\bPREEMPT\b", version) else "none or voluntary"


def _boot_log_line(prefix: str) -> str:
    """The rest of the kernel log's first line that starts with ``prefix`` ("" if none or not readable)."""
    try:
        fd = os.open("/dev/kmsg", os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return ""
    try:
        while True:
            try:
                record = os.read(fd, 8192).decode(errors="replace")
            except BlockingIOError:
                return ""
            except OSError:  # EPIPE: a record overwritten while read; the next read goes on
                continue
            if not record:
                return ""
            text = record.split(";", 1)[-1].strip()
            if text.startswith(prefix):
                return text[len(prefix):].strip()
    finally:
        os.close(fd)


def _limit(which: int) -> str:
    soft, _ = resource.getrlimit(which)
    return "unlimited" if soft == resource.RLIM_INFINITY else str(soft)


def system_checks() -> list[Check]:
    """The machine's checks (the page faults come from the loop)."""
    checks: list[Check] = []
    version = platform.uname().version
    rt = "PREEMPT_RT" in version or _read("/sys/kernel/realtime") == "1"
    mode = "rt" if rt else preemption(version)
    fix = ("install a PREEMPT_RT kernel (Debian: linux-image-rt-amd64; Ubuntu: the real-time kernel of Ubuntu Pro) "
           "for bounded latency; a lowlatency kernel helps too")
    if mode in ("none", "voluntary", "none or voluntary"):
        fix += ("; at least boot this one with preempt=full (without it a real-time thread waits for other "
                "processes' system calls)")
    checks.append(("kernel", rt, f"{platform.release()} {version}" + (" (PREEMPT_RT)" if rt else " (not PREEMPT_RT)")
                   + f", preemption {mode}", fix))
    rt_runtime = _read("/proc/sys/kernel/sched_rt_runtime_us")
    fifo_ok = _can_fifo()
    checks.append(("SCHED_FIFO", fifo_ok,
                   (f"{'allowed' if fifo_ok else 'refused'} (rtprio limit {_limit(resource.RLIMIT_RTPRIO)}, "
                   f"CAP_SYS_NICE {'yes' if capability(CAP_SYS_NICE) else 'no'}, sched_rt_runtime_us "
                   f"{rt_runtime or 'unknown'})"), FIFO_FIX))
    memlock = resource.getrlimit(resource.RLIMIT_MEMLOCK)[0]
    lock_ok = memlock == resource.RLIM_INFINITY or capability(CAP_IPC_LOCK)
    checks.append(("memory locking", lock_ok,
                   (f"memlock limit {_limit(resource.RLIMIT_MEMLOCK)}, CAP_IPC_LOCK "
                   f"{'yes' if capability(CAP_IPC_LOCK) else 'no'}"), MEMLOCK_FIX))
    cpus = Path("/sys/devices/system/cpu")
    governors = sorted({_read(str(p)) for p in cpus.glob("cpu[0-9]*/cpufreq/scaling_governor")})
    if not governors:
        checks.append(("CPU governor", True, "no cpufreq interface (fixed frequency, e.g. a virtual machine)", ""))
    else:
        checks.append(("CPU governor", governors == ["performance"], ", ".join(governors),
                       ("cpupower frequency-set -g performance (or echo performance into "
                       "/sys/devices/system/cpu/cpu*/cpufreq/scaling_governor)")))
    isolated = _read("/sys/devices/system/cpu/isolated")
    checks.append(("isolated cores", bool(isolated), isolated or "none",
                   "isolate a core for the loop: isolcpus=N nohz_full=N rcu_nocbs=N on the kernel command line, "
                   "then the nodes' cpu_affinity:=[N] (rt-check --cpu N); " + AFFINITY_FIX))
    return checks


def _can_fifo() -> bool:
    """Whether this thread may switch to SCHED_FIFO (tried at priority 1 and switched back)."""
    try:
        before = os.sched_getscheduler(0), os.sched_getparam(0)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        os.sched_setscheduler(0, before[0], before[1])
    except OSError:
        return False
    return True


def paced_loop(period: float, duration: float, busy_wait: float, *,
               stop: threading.Event | None = None) -> tuple[np.ndarray, np.ndarray, LoopStatistics]:
    """Tick at ``period`` for ``duration`` s, or until ``stop`` is set: the lateness of each tick
    start and the tick starts (``perf_counter`` seconds), both after ``WARM_UP_S``, and the loop's
    statistics (the nodes' own :class:`~pdsmc_ros.loop.statistics.LoopStatistics`, warmed up for
    ``WARM_UP_S``: missed ticks, page faults).

    Paced as the serve loop paces the nodes: sleep until ``busy_wait`` before the deadline,
    spin the rest; a tick more than a period behind resynchronises.
    """
    clock, sleep = time.perf_counter, time.sleep
    n = int(duration / period) + 1
    late = np.zeros(n)
    starts = np.zeros(n)
    warm = max(min(int(WARM_UP_S / period), n - 2), 0)
    stats = LoopStatistics(period, warm_up=warm)
    deadline = clock() + period
    ticks = 0
    while ticks < n and (stop is None or not stop.is_set()):
        left = deadline - busy_wait - clock()
        if left > 0.0:
            sleep(left)
        while clock() < deadline:
            pass
        start = clock()
        late[ticks] = start - deadline
        starts[ticks] = start
        stats.start(late[ticks], start)
        ticks += 1
        if ticks == warm:
            stats.page_faults(minor_faults())  # the warm-up's end
        deadline += period
        if start - deadline > period:
            deadline = start + period
    stats.page_faults(minor_faults())
    return late[warm:ticks], starts[warm:ticks], stats


def histogram(late_us: np.ndarray) -> str:
    edges = (0, *BUCKETS_US[:-1])
    parts = [f"<{hi} us: {int(np.count_nonzero((late_us >= lo) & (late_us < hi)))}"
             for lo, hi in zip(edges, BUCKETS_US, strict=True)]
    parts.append(f">={BUCKETS_US[-1]} us: {int(np.count_nonzero(late_us >= BUCKETS_US[-1]))}")
    return ", ".join(parts)


def run(args: argparse.Namespace) -> int:
    settings, period, duration, busy_wait = settings_from(args)
    checks = system_checks()
    collector = Collector()
    collector.start()
    applied = apply(settings)
    try:
        late, starts, stats = paced_loop(period, duration, busy_wait)
        faults = stats.faults
        summary = applied.summary()
    finally:
        restore(applied)
        collector.stop()
    checks.append(("page faults", faults == 0, f"{faults} minor faults in the loop after {WARM_UP_S:g} s of warm-up",
                   "lock memory (lock_memory, see memory locking) and allocate nothing new in the loop"))
    width = max(len(c[0]) for c in checks)
    for name, passed, found, fix in checks:
        print(f"{name:{width}s}  {'ok  ' if passed else 'FAIL'}  {found}")
        if not passed:
            print(f"{'':{width}s}        fix: {fix}")
    if applied.warning:
        print(applied.warning)
    print(f"loop: {len(late)} ticks at {1 / period:g} Hz after {WARM_UP_S:g} s of warm-up; {summary}; "
          f"busy-wait {1e6 * busy_wait:g} us")
    late_us, jitter_us = 1e6 * late, 1e6 * np.abs(np.diff(starts) - period)
    for label, values in (("late (tick start - deadline)", late_us), ("jitter |period - nominal|", jitter_us)):
        p50, p99, p999 = np.percentile(values, (50, 99, 99.9))
        print(f"{label}: p50 {p50:.1f} us, p99 {p99:.1f} us, p99.9 {p999:.1f} us, max {values.max():.1f} us, "
              f"mean {values.mean():.1f} us")
    print(f"histogram of lateness: {histogram(late_us)}")
    missed = stats.missed
    print(f"missed periods (a tick more than a period late): {missed} of {stats.ticks} "
          f"({100.0 * missed / max(stats.ticks, 1):.3f} %); mean lateness {100 * late.mean() / period:.2f} % of the "
          "period (ROS 2's real-time demo asks for < 3 %)")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pdsmc_ros.loop.rt_check``: the same as ``pdsmc rt-check`` (its own parser: nothing
    imports the command line)."""
    parser = OneLineParser(prog="pdsmc rt-check", description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except InvalidInputError as exc:
        print(f"pdsmc rt-check: error: {exc}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    raise SystemExit(main())
