"""``scripts/run_experiment.sh``'s stand-in flags refused where they do not belong: one line, exit 2,
before anything starts (no ROS: the script stops at its arguments)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "run_experiment.sh"


@pytest.mark.parametrize(("extra", "message"), [
    (["--driver-param", "payload_mass:=2.0"], "--driver-param goes with --stand-in"),
    (["--realism", "bench"], "--realism goes with --stand-in"),
])
def test_a_stand_in_flag_without_the_stand_in_is_refused(tmp_path: Path, extra: list[str], message: str) -> None:
    out = tmp_path / "run"
    proc = subprocess.run(["bash", str(SCRIPT), "--robot", "serial_3r", "--contour", "circle", "--controller", "pd",
                           "--out", str(out), *extra], capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], proc.stderr
    assert not out.exists()
