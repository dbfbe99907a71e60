"""``pdsmc rt-check``: runs a short loop and reports every check and the latency histogram;
bad input is one line and exit 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent.parent


def rt_check(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pdsmc_ros.loop.rt_check", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)


def test_rt_check_runs_and_reports_each_check_and_the_histogram() -> None:
    proc = rt_check("--duration", "1.5", "--priority", "1")
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    for name in ("kernel", "SCHED_FIFO", "memory locking", "CPU governor", "isolated cores", "page faults"):
        assert any(line.startswith(name) and (" ok " in line or " FAIL " in line) for line in out.splitlines()), out
    for line in out.splitlines():  # every failing check comes with its fix on the next line
        if " FAIL " in line:
            following = out.splitlines()[out.splitlines().index(line) + 1]
            assert following.strip().startswith("fix: "), out
    assert "late (tick start - deadline): p50 " in out and " p99 " in out and " p99.9 " in out and " max " in out
    assert "histogram of lateness: <10 us: " in out
    assert "missed periods (a tick more than a period late): " in out
    ticks = int(out.split("\nloop: ")[1].split(" ticks")[0])
    assert ticks == 501  # 1.5 s at 1 kHz, the first second of warm-up left out


@pytest.mark.parametrize(("args", "message"), [
    (["--duration", "-1"], "--duration must be seconds in [0.1, 3600]"),
    (["--priority", "100"], "--priority must be a whole number in [0, 99]"),
    (["--cpu", "x"], "--cpu takes core numbers separated by commas"),
    (["--busy-wait", "0.5"], "--busy-wait must be seconds in [0, 0.001]"),
])
def test_rt_check_bad_input_is_one_line_and_exit_2(args: list[str], message: str) -> None:
    proc = rt_check(*args)
    assert proc.returncode == 2
    assert message in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


@pytest.mark.parametrize(("version", "debugfs", "cmdline", "boot_log", "mode"), [
    ("#1 SMP PREEMPT_RT Thu", "", "", "", "rt"),
    ("#1 SMP PREEMPT_DYNAMIC @0", "none voluntary (full) lazy", "preempt=none", "none", "full"),
    ("#1 SMP PREEMPT_DYNAMIC @0", "", "quiet preempt=voluntary panic=1", "none", "voluntary"),
    ("#1 SMP PREEMPT_DYNAMIC @0", "", "quiet panic=1", "none", "none"),
    ("#1 SMP PREEMPT Thu Jan 1", "", "", "", "full"),
    ("#1 SMP Thu Jan 1", "", "", "", "none or voluntary"),
])
def test_preemption_mode_from_the_first_source_that_tells(monkeypatch, version, debugfs, cmdline, boot_log,
                                                           mode) -> None:
    from pdsmc_ros.loop import rt_check as module

    files = {"/sys/kernel/debug/sched/preempt": debugfs, "/proc/cmdline": cmdline}
    monkeypatch.setattr(module, "_read", lambda path: files.get(path, ""))
    monkeypatch.setattr(module, "_boot_log_line", lambda prefix: boot_log)
    assert module.preemption(version) == mode


def test_preemption_mode_says_when_it_cannot_tell(monkeypatch) -> None:
    from pdsmc_ros.loop import rt_check as module

    monkeypatch.setattr(module, "_read", lambda path: "")
    monkeypatch.setattr(module, "_boot_log_line", lambda prefix: "")
    assert module.preemption("#1 SMP PREEMPT_DYNAMIC @0").startswith("dynamic (mode unknown")
