"""Sweeps, Lyapunov conditions and plots (Section 4.2.3, Eq. 3.19)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from pdsmc_ros.control import Gains
from pdsmc_ros.control.lyapunov import theorem_conditions
from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.experiments.sweep import sweep_specs, thesis_values
from pdsmc_ros.runs.builder import make_run


def test_thesis_increments_of_table_4_15() -> None:
    assert thesis_values(10, 10000)[:11] == [10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 200]
    assert thesis_values(10, 10000)[-3:] == [8000, 9000, 10000]
    assert len(thesis_values(10, 10000)) == 28
    assert thesis_values(0, 200)[:12] == [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 20]
    assert thesis_values(1, 200)[-1] == 200


def test_sweep_runs_each_point_at_a_stable_rate() -> None:
    param, specs = sweep_specs("kd", "serial_3r", "circle")
    assert param == "kd"
    assert [s.gains["kd"][0] for s in specs][-1] == 10000.0
    # Kd = 10000 with the serial arm's inertia needs a faster loop than the default 10 kHz
    assert specs[-1].rate > 10000.0 and specs[0].rate == 10000.0
    assert all(s.gains["kp"] == (5000.0,) * 3 and s.gains["phi"] == (0.5,) * 3 for s in specs)


def test_any_law_sweeps_any_gain_it_declares_from_its_presets() -> None:
    presets = make_run("parallel_5r", "circle", "sta").gains
    param, specs = sweep_specs("k2", "parallel_5r", "circle", [1.0, 50.0], controller="sta")
    assert param == "k2" and [s.controller for s in specs] == ["sta", "sta"]
    assert [s.gains["k2"] for s in specs] == [(1.0, 1.0), (50.0, 50.0)]
    assert all(s.gains["k1"] == presets["k1"] and s.gains["lam"] == presets["lam"] for s in specs)
    with pytest.raises(InvalidInputError, match="no range for sta's k2: give the values"):
        sweep_specs("k2", "parallel_5r", "circle", controller="sta")
    with pytest.raises(InvalidInputError, match="unknown sweep parameter 'phi' of sta; choose one of: k1, k2, lam"):
        sweep_specs("phi", "parallel_5r", "circle", [1.0], controller="sta")


def test_theorem_conditions_hold_for_thesis_gains_and_fail_for_weak_ks() -> None:
    spec = make_run("serial_3r", "circle", "pdsmc")
    conds = theorem_conditions(spec, points=101)
    assert all(c.holds for c in conds), [c for c in conds if not c.holds]
    weak = make_run("serial_3r", "circle", "pdsmc",
                    gains=Gains.from_mapping({"kp": [9200, 8300, 2200], "kd": [2400, 1600, 1400],
                                              "ks": [1, 35, 25], "lam": [22, 15, 10],
                                              "phi": [0.25, 0.3, 0.25]}, 3, "pdsmc"))
    failing = [c.name for c in theorem_conditions(weak, points=101) if not c.holds]
    assert failing == ["Ks_1 > max |tau_d,1|"]


def test_check_gains_cli_reports_each_condition() -> None:
    proc = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "check-gains", "--robot", "serial_3r",
                           "--contour", "circle", "--controller", "pdsmc", "--rate", "5000", "--mode", "lockstep"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stderr  # the rate condition fails at 5 kHz
    assert proc.stdout.count("holds ") == 9  # lambda, Ks x 3, K + C^T and the four gain bounds
    assert "discrete-rate condition at 5000 Hz FAILS" in proc.stdout
    assert "lowest stable rate 9,011 Hz" in proc.stdout


def test_sweep_cli_writes_table_and_plot(tmp_path) -> None:  # noqa: ANN001
    proc = subprocess.run([sys.executable, "-m", "pdsmc_ros.cli", "sweep", "--param", "lam", "--robot",
                           "parallel_5r", "--contour", "ellipse_vertical", "--values", "0,10,100",
                           "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    rows = (tmp_path / "sweep_lam.csv").read_text().splitlines()
    assert len(rows) == 1 + 3
    png = (tmp_path / "sweep_lam.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    means = np.array([float(r.split(",")[2]) for r in rows[1:]])
    assert np.all(np.isfinite(means)) and np.all(means > 0)
