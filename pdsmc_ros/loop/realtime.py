"""Real-time settings of a control loop's thread, named as ros2_control's (ROS-free).

ros2_control's controller manager runs its update loop in a thread it configures with
``realtime_tools``: ``SCHED_FIFO`` at ``thread_priority`` (50 by default), optionally pinned
to ``cpu_affinity`` and with the process's memory locked (``lock_memory``,
``mlockall(MCL_CURRENT | MCL_FUTURE)``). Where the system refuses (no privilege, limits), it
warns and runs on at normal scheduling; so does :func:`apply` here, with one warning that
names the fix (``/etc/security/limits.conf`` ``rtprio``/``memlock``, or the capability).

The scheduling policy and the affinity are per thread on Linux (``sched_setscheduler(0)``
and ``sched_setaffinity(0)`` act on the calling thread): they are applied by the loop's own
thread, after the process's other threads (the executor's, Fast DDS's) exist. Those go to
``SCHED_FIFO`` priority 1 (:func:`raise_helpers`: below the loop, above the machine's normal
load, which would otherwise preempt one holding the GIL or a DDS lock the loop waits for) and
to the same cores (:func:`pin_helpers`). Memory locking is per process. Both policies carry
``SCHED_RESET_ON_FORK``: a process started from a real-time thread (the gain check's,
:mod:`pdsmc_ros.controller.sidecar.gain_check`) starts at normal scheduling, never at the loop's
priorities, where its start-up (a Python interpreter's imports, about a second of CPU) would
starve the machine's normal processes -- a driver among them.

Python's garbage collector is kept out of the loop (:class:`Collector`): everything alive
after start-up is frozen (``gc.freeze``: never scanned again), automatic collection is off,
and the young generation is collected only where the loop says it has time to spare.
"""

from __future__ import annotations

import ctypes
import dataclasses
import gc
import os
import resource
import threading
from collections.abc import Sequence
from pathlib import Path

from ..errors import ConfigError
from ..glibc import M_MMAP_MAX, M_TRIM_THRESHOLD, libc, mallopt
from ..parameters.tables import DEFAULT_PRIORITY, MAX_PRIORITY

BUSY_WAIT_S = 0.0002  # seconds spun before each tick at normal priority (the nodes' busy_wait default)
FIFO_BUSY_WAIT_S = 0.00005  # at SCHED_FIFO unless busy_wait is given: a FIFO thread wakes on time
# ... except for about 1 % of its wake-ups from a sleep (cyclictest: docs/PERFORMANCE.md): a
# process whose one thread ticks several loop nodes (composed) spins this long instead, beyond
# the wake-ups' p99.9; separate loop processes keep FIFO_BUSY_WAIT_S, since three FIFO loops
# spinning at the same instants on two cores wait for one another
FIFO_COMPOSED_BUSY_WAIT_S = 0.0003
FIFO_BUSY_SHARE = 0.5  # at SCHED_FIFO: the share of a period the loop may spin at most
# mlockall flags of Linux on x86, arm and riscv (<bits/mman-linux.h>)
MCL_CURRENT, MCL_FUTURE = 1, 2

FIFO_FIX = ("allow it with 'rtprio 99' for the user in /etc/security/limits.conf (then log in again) "
            "or give the process CAP_SYS_NICE (setcap cap_sys_nice+ep, or a container's --cap-add SYS_NICE)")
MEMLOCK_FIX = ("allow it with 'memlock unlimited' for the user in /etc/security/limits.conf (then log in "
               "again) or give the process CAP_IPC_LOCK (a container's --cap-add IPC_LOCK)")
AFFINITY_FIX = "choose cores this process may use (taskset -p <pid>, the container's cpuset)"


@dataclasses.dataclass(frozen=True)
class RealtimeSettings:
    """What a ticking node asks of the system for its loop.

    Attributes
    ----------
    thread_priority : int
        ``SCHED_FIFO`` priority of the loop's thread, 1-99; 0 keeps normal scheduling.
    cpu_affinity : tuple of int
        Cores the loop's thread may run on; empty keeps the inherited set.
    lock_memory : bool
        Lock the process's pages in memory, present and future (no page-in in the loop).
    """

    thread_priority: int = 0
    cpu_affinity: tuple[int, ...] = ()
    lock_memory: bool = False

    @classmethod
    def for_mode(cls, mode: str, priority: int = DEFAULT_PRIORITY) -> RealtimeSettings:
        """The defaults: ros2_control's in ``realtime`` (FIFO ``priority``, memory locked), none in lockstep."""
        if mode == "realtime":
            return cls(thread_priority=priority, lock_memory=True)
        return cls()

    def validated(self) -> RealtimeSettings:
        """``self``, or a ConfigError naming the setting and what is allowed."""
        if not 0 <= self.thread_priority <= MAX_PRIORITY:
            raise ConfigError(f"thread_priority must be a whole number in [0, {MAX_PRIORITY}] "
                              f"(0: normal scheduling), got {self.thread_priority}")
        cores = os.cpu_count() or 1
        bad = [c for c in self.cpu_affinity if not 0 <= c < cores]
        if bad:
            raise ConfigError(f"cpu_affinity must list cores in [0, {cores - 1}] (this machine has {cores}), "
                              f"got {list(self.cpu_affinity)}")
        return self

    @staticmethod
    def merged(settings: Sequence[RealtimeSettings]) -> RealtimeSettings:
        """Several nodes composed in one loop: the highest priority, every core asked for, and
        memory locked if any node asks (one thread ticks them all)."""
        if not settings:
            return RealtimeSettings()
        cores = sorted({c for s in settings for c in s.cpu_affinity})
        return RealtimeSettings(max(s.thread_priority for s in settings), tuple(cores),
                                any(s.lock_memory for s in settings))


@dataclasses.dataclass
class Applied:
    """What :func:`apply` achieved, and the one warning for what the system refused (or "")."""

    fifo: bool = False
    affinity: tuple[int, ...] = ()
    memory_locked: bool = False
    warning: str = ""
    helpers: list[int] = dataclasses.field(default_factory=list)  # threads raised by raise_helpers
    reserved: int = 0  # bytes kept for the loop's later allocations (reserve_memory)

    def summary(self) -> str:
        """One line for the node's log."""
        parts = [f"SCHED_FIFO priority {os.sched_getparam(0).sched_priority}" if self.fifo else "normal scheduling",
                 f"cores {','.join(map(str, self.affinity))}" if self.affinity else "any core",
                 (f"memory locked ({self.reserved >> 20} MiB reserved)" if self.memory_locked
                  else "memory not locked"),
                 f"{len(self.helpers)} other threads at FIFO {HELPER_PRIORITY}" if self.helpers else ""]
        return "real time: " + ", ".join(p for p in parts if p)


def lock_memory() -> str:
    """``mlockall(MCL_CURRENT | MCL_FUTURE)``; "" on success, else the reason it was refused."""
    if libc().mlockall(MCL_CURRENT | MCL_FUTURE) == 0:
        return ""
    err = ctypes.get_errno()
    soft, _ = resource.getrlimit(resource.RLIMIT_MEMLOCK)
    limit = "unlimited" if soft == resource.RLIM_INFINITY else f"{soft // 1024} KiB"
    return f"{os.strerror(err)} (memlock limit {limit})"


HEAP_RESERVE_BYTES = 32 << 20
"""Freed C heap a memory-locked loop keeps for what it allocates later (numpy arrays, messages)."""
OBJECT_RESERVE_BYTES = 16 << 20
"""Free room in Python's small-object arenas a memory-locked loop keeps for its objects."""
_RESERVE_BLOCK = 1 << 20
_arena_keepers: list[object] = []  # one live object per reserved arena: an empty arena is given back


def reserve_memory(heap_bytes: int = HEAP_RESERVE_BYTES, object_bytes: int = OBJECT_RESERVE_BYTES) -> int:
    """Memory the calling thread can allocate from later without a page fault; the bytes reserved.

    Called after :func:`lock_memory`, by the loop's thread. With ``MCL_FUTURE`` every page the
    process maps from then on is faulted in when it is mapped: a loop that grows its heap, or
    Python's objects that need a new arena (1 MiB), takes hundreds of faults in one tick (41 and
    256 were seen after warm-up, docs/PERFORMANCE.md). So, as ROS 2's real-time demo does
    before its loop, glibc keeps what is freed (no ``mmap``'d allocations, no trimming), the heap
    is grown by ``heap_bytes`` and freed, and Python's allocator gets ``object_bytes`` of arenas,
    kept with one live object each and otherwise free. Both stay locked and resident. Under a
    finite ``memlock`` limit, at most half of the room left is reserved (past the limit, a locked
    process's allocations fail).
    """
    soft, _ = resource.getrlimit(resource.RLIMIT_MEMLOCK)
    if soft != resource.RLIM_INFINITY and not capability(CAP_IPC_LOCK):
        quarter = max(0, soft - locked_kib() * 1024) // 4  # each reserve a quarter of the room: half in all
        heap_bytes, object_bytes = min(heap_bytes, quarter), min(object_bytes, quarter)
    reserved = 0
    if heap_bytes > 0 and mallopt(M_MMAP_MAX, 0) and mallopt(M_TRIM_THRESHOLD, -1):
        # blocks below a thread heap's size (64 MiB): from the calling thread's own malloc arena
        blocks = [bytearray(_RESERVE_BLOCK) for _ in range(heap_bytes // _RESERVE_BLOCK)]
        reserved += len(blocks) * _RESERVE_BLOCK
        del blocks
    if object_bytes > 0:
        objects = [(i, -i) for i in range(object_bytes // 64)]  # a 2-tuple takes 56 of an arena's bytes
        kept: dict[int, object] = {}
        for obj in objects:
            kept.setdefault(id(obj) >> 20, obj)
        _arena_keepers.extend(kept.values())
        reserved += len(objects) * 64
        del objects
    return reserved


def unlock_memory() -> None:
    """``munlockall()``: the loop is over (tear-down need not stay resident)."""
    libc().munlockall()


FIFO = os.SCHED_FIFO | os.SCHED_RESET_ON_FORK
"""The loop's and its helpers' policy: SCHED_FIFO, and a child process starts at normal scheduling."""


def policy_of(tid: int) -> int:
    """Thread ``tid``'s scheduling policy (0: the calling thread), without ``SCHED_RESET_ON_FORK``."""
    return os.sched_getscheduler(tid) & ~os.SCHED_RESET_ON_FORK


def set_fifo(priority: int) -> str:
    """The calling thread to ``SCHED_FIFO`` at ``priority`` (0: normal); "" or the refusal."""
    try:
        if priority > 0:
            os.sched_setscheduler(0, FIFO, os.sched_param(priority))
        else:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except OSError as exc:
        soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
        return f"{exc.strerror} (rtprio limit {soft})"
    return ""


HELPER_PRIORITY = 1  # SCHED_FIFO priority of the process's other threads while the loop runs at FIFO


def raise_helpers(priority: int = HELPER_PRIORITY) -> list[int]:
    """The process's other threads (Fast DDS's, the executor's) to ``SCHED_FIFO`` at ``priority``,
    below the loop's; the thread ids changed.

    The loop thread waits for them: for the GIL (the executor thread) and for the DDS writer's
    locks a publish takes (Fast DDS's event and receive threads). At normal priority, a
    loaded machine preempts them for milliseconds while they hold one -- the FIFO loop then
    waits as long (priority inversion). A FIFO thread is preempted only by higher priorities.
    """
    own = threading.get_native_id()
    changed = []
    for entry in os.listdir("/proc/self/task"):
        tid = int(entry)
        if tid == own:
            continue
        try:
            if policy_of(tid) != os.SCHED_OTHER:
                continue
            os.sched_setscheduler(tid, FIFO, os.sched_param(priority))
        except OSError:  # refused (as the loop's own) or the thread has ended
            continue
        changed.append(tid)
    return changed


def lower_helpers(tids: Sequence[int]) -> None:
    """Undo :func:`raise_helpers`."""
    for tid in tids:
        try:
            os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
        except OSError:  # the thread has ended
            continue


def pin_helpers(cores: Sequence[int]) -> None:
    """The process's other threads on ``cores`` too: a message reaches the loop through Fast
    DDS's receive thread, and a hand-off on one core is cheaper than across cores."""
    own = threading.get_native_id()
    for entry in os.listdir("/proc/self/task"):
        if int(entry) != own:
            try:
                os.sched_setaffinity(int(entry), cores)
            except OSError:  # the thread has ended
                continue


def apply(settings: RealtimeSettings) -> Applied:
    """Apply ``settings`` to the calling thread (and, for memory, the process).

    Refusals do not raise: each is described in ``Applied.warning`` (one line, with its fix)
    and the loop runs on without it, as ros2_control's controller manager does.
    """
    applied = Applied()
    refused = []
    if settings.cpu_affinity:
        try:
            os.sched_setaffinity(0, settings.cpu_affinity)
            applied.affinity = tuple(sorted(os.sched_getaffinity(0)))
            pin_helpers(settings.cpu_affinity)
        except OSError as exc:
            refused.append(f"cpu_affinity {list(settings.cpu_affinity)} ({exc.strerror}): {AFFINITY_FIX}")
    if settings.lock_memory:
        why = lock_memory()
        applied.memory_locked = not why
        if applied.memory_locked:
            applied.reserved = reserve_memory()
        if why:
            refused.append(f"lock_memory ({why}): {MEMLOCK_FIX}")
    if settings.thread_priority > 0:
        why = set_fifo(settings.thread_priority)
        applied.fifo = not why
        if applied.fifo and settings.thread_priority > HELPER_PRIORITY:
            applied.helpers = raise_helpers()
        if why:
            refused.append(f"SCHED_FIFO priority {settings.thread_priority} ({why}): {FIFO_FIX}")
    if refused:
        applied.warning = "real time: running on without " + "; without ".join(refused)
    return applied


def restore(applied: Applied) -> None:
    """Undo :func:`apply` at the end of the loop: normal scheduling (tear-down at FIFO could
    starve the machine if it spun), memory unlocked. The affinity stays."""
    lower_helpers(applied.helpers)
    if applied.fifo:
        set_fifo(0)
    if applied.memory_locked:
        unlock_memory()


def scheduler_of_thread() -> tuple[str, int]:
    """The calling thread's policy name and priority (read back, e.g. in tests)."""
    policy = policy_of(0)
    names = {os.SCHED_OTHER: "SCHED_OTHER", os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR",
             os.SCHED_BATCH: "SCHED_BATCH", os.SCHED_IDLE: "SCHED_IDLE"}
    return names.get(policy, str(policy)), os.sched_getparam(0).sched_priority


SELF_STATUS = Path("/proc/self/status")
CAP_IPC_LOCK, CAP_SYS_NICE = 14, 23  # bits of CapEff (linux/capability.h)


def _status_field(name: str, status: Path) -> str:
    """The first word of field ``name`` in a ``/proc/<pid>/status`` file ("" if it cannot be read)."""
    try:
        for line in status.read_text().splitlines():
            if line.startswith(f"{name}:"):
                return line.split()[1]
    except (OSError, IndexError):
        return ""
    return ""


def locked_kib(status: Path = SELF_STATUS) -> int:
    """``VmLck`` of ``/proc/self/status`` in KiB: the process's locked memory (0 if unknown)."""
    value = _status_field("VmLck", status)
    return int(value) if value.isdigit() else 0


def capability(bit: int, status: Path = SELF_STATUS) -> bool:
    """Whether the process holds capability ``bit`` (``CapEff`` of ``/proc/self/status``): with
    :data:`CAP_IPC_LOCK` it may lock memory beyond ``RLIMIT_MEMLOCK``, with :data:`CAP_SYS_NICE` set
    ``SCHED_FIFO`` beyond ``RLIMIT_RTPRIO``."""
    try:
        return bool(int(_status_field("CapEff", status) or "0", 16) >> bit & 1)
    except ValueError:
        return False


def minor_faults() -> int:
    """Minor page faults of the calling thread so far (``getrusage(RUSAGE_THREAD)``)."""
    return resource.getrusage(resource.RUSAGE_THREAD).ru_minflt


YOUNG_COLLECT_AT = 2_000  # young-generation collections happen when this many objects are pending


class Collector:
    """Python's garbage collector kept out of the loop.

    :meth:`start` collects everything, freezes what is alive (the nodes, the kernels, the
    references: never scanned again) and turns automatic collection off, so a collection
    never starts inside a tick. :meth:`idle` collects the young generation only when the
    loop calls it with time to spare and enough objects are pending: a young collection of
    ``YOUNG_COLLECT_AT`` objects takes tens of microseconds, against milliseconds for the
    automatic full collections a long run would otherwise meet at a random tick.
    """

    def __init__(self, young_at: int = YOUNG_COLLECT_AT) -> None:
        self.young_at = young_at
        self.collections = 0
        self._was_enabled = gc.isenabled()

    def start(self) -> None:
        gc.collect()
        gc.freeze()
        gc.disable()

    def idle(self) -> bool:
        """The loop has time: collect the young generation if enough is pending."""
        if gc.get_count()[0] < self.young_at:
            return False
        gc.collect(0)
        self.collections += 1
        return True

    def stop(self) -> None:
        if self._was_enabled:
            gc.enable()
        gc.unfreeze()


def busy_wait_for(requested: float, *, fifo: bool, loops: int, period: float | None) -> float:
    """The seconds a paced loop spins before each tick instead of sleeping.

    Parameters
    ----------
    requested : float
        ``AUTO_BUSY_WAIT`` (the nodes' default), or seconds the user gave (kept, up to the cap).
    fifo : bool
        Whether the loop's thread runs at ``SCHED_FIFO``.
    loops : int
        How many loop nodes the thread ticks (more than one: a composed process).
    period : float or None
        The loop's period in seconds; None when it is not paced (lockstep).

    Returns
    -------
    float
        Automatic: ``BUSY_WAIT_S`` at normal priority (sleeps wake late there); at FIFO
        ``FIFO_BUSY_WAIT_S``, or ``FIFO_COMPOSED_BUSY_WAIT_S`` for several loops. At FIFO never
        more than ``FIFO_BUSY_SHARE`` of the period: a FIFO thread that never sleeps is stopped
        by the kernel's real-time throttling (``sched_rt_runtime_us``).
    """
    if requested < 0.0:
        if not fifo:
            return BUSY_WAIT_S
        requested = FIFO_COMPOSED_BUSY_WAIT_S if loops > 1 else FIFO_BUSY_WAIT_S
    if fifo and period:
        return min(requested, FIFO_BUSY_SHARE * period)
    return requested
