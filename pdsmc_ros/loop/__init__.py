"""The one owner of a ticking process's loop: running nodes in a process (process.py), the serve
loop and the group of nodes it ticks (serve.py), its inputs (inputs.py, intra.py), the executor's
thread (executor_thread.py), the loop's log (log.py), the process lifecycle (lifecycle.py),
real-time settings (realtime.py, realtime_params.py), the loop statistics and missed deadlines
(statistics.py) and ``pdsmc rt-check`` (rt_check.py)."""
