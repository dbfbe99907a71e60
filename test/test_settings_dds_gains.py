"""One gain resolver (issue 39): a scenario, a params file and an override give the same gains and the
same run in-process (``pdsmc simulate``) and over DDS (``scripts/run_experiment.sh``), to 1e-9."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from test_ros_e2e import run_experiment

from pdsmc_ros import cli
from pdsmc_ros.bag.reader import read_run, run_metrics
from pdsmc_ros.sim import simulate

PD_FILE = {"controller": {"ros__parameters": {"kp": [8000.0, 8000.0, 3000.0], "kd": [500.0, 500.0, 150.0]}}}
"""Issue 39's pd.yaml."""


@pytest.mark.timeout(300)
def test_scenario_params_file_and_override_over_dds_equal_in_process(ros_env: dict, tmp_path: Path) -> None:
    path = tmp_path / "pd.yaml"
    path.write_text(yaml.safe_dump(PD_FILE))
    run = ["--robot", "serial_3r", "--contour", "circle", "--controller", "pd", "--scenario", "high_pd"]
    args = cli.build_parser().parse_args(["simulate", *run, "--params-file", str(path), "--gain", "kd=400,500,150"])
    in_process = cli.spec_from_args(args)
    # the documented composition: the file's gains, the override over them, then high_pd's x1.5 on both
    assert in_process.gains["kp"] == (12000.0, 12000.0, 4500.0)
    assert in_process.gains["kd"] == (600.0, 750.0, 225.0)
    out = tmp_path / "dds"
    proc = run_experiment(ros_env, out, *run, "--params-file", str(path), "--param", "kd:=[400.0, 500.0, 150.0]",
                          "--duration-factor", "0.1")
    assert proc.returncode == 0, proc.stderr
    recorded = read_run(out)
    assert recorded.complete and recorded.spec.gains == in_process.gains  # the controller ran exactly these
    sim = simulate(recorded.spec)
    every = recorded.spec.sample_every
    assert np.max(np.abs(recorded.q[::every] - sim.samples.q)) <= 1e-9
    assert np.max(np.abs(recorded.tau[::every] - sim.samples.tau)) <= 1e-9
    assert run_metrics(recorded).contour_mean == pytest.approx(sim.metrics.contour_mean, rel=1e-9)
