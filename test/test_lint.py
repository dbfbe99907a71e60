"""Lint as a test (ros2 packages carry test_flake8): ruff with the repository's ruff.toml."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "ruff.toml"


def ruff() -> list[str]:
    found = shutil.which("ruff", path=str(Path(sys.executable).parent))
    if found is None:
        pytest.fail("ruff is not installed in this environment (make setup installs requirements-test.txt)")
    return [found]


def test_the_package_tests_and_benchmarks_are_lint_clean() -> None:
    proc = subprocess.run([*ruff(), "check", "--config", str(CONFIG), "pdsmc_ros", "test", "bench"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.parametrize(("source", "rule"), [
    ("try:\n    pass\nexcept:\n    pass\n", "E722"),  # bare except
    ("def f(x=[]):\n    return x\n", "B006"),  # mutable default
    ("from os import *\n", "F403"),  # star import
])
def test_the_configuration_catches_what_the_style_guide_forbids(tmp_path: Path, source: str, rule: str) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text(source)
    proc = subprocess.run([*ruff(), "check", "--config", str(CONFIG), "--output-format", "concise", str(bad)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1 and rule in proc.stdout, proc.stdout + proc.stderr
