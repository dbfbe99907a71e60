"""A law with internal state over DDS: ``ros2 run pdsmc_ros controller -p type:=sta`` in lockstep
integrates its state as the in-process run does (reset on activation, nominal period 1/rate)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from test_ros_e2e import run_experiment

from pdsmc_ros.bag.reader import read_run
from pdsmc_ros.sim import simulate


@pytest.mark.timeout(300)
def test_lockstep_super_twisting_equals_in_process(ros_env: dict, tmp_path: Path) -> None:
    out = tmp_path / "five_bar_sta"
    proc = run_experiment(ros_env, out, "--robot", "parallel_5r", "--contour", "circle", "--controller", "sta",
                          "--duration-factor", "0.05")
    assert proc.returncode == 0, proc.stderr
    run = read_run(out)
    assert run.complete and run.description["controller"] == "sta" and "k2" in run.description["gains"]
    sim = simulate(run.spec)
    every = run.spec.sample_every
    assert np.max(np.abs(run.q[::every] - sim.samples.q)) <= 1e-9
    assert np.max(np.abs(run.tau[::every] - sim.samples.tau)) <= 1e-9
    # the state mattered: with v held near zero (k2 x 1e-9) the in-process run is another run
    frozen = simulate(dataclasses.replace(run.spec, gains=run.spec.gains.scaled({"k2": 1e-9})))
    assert np.max(np.abs(run.tau[::every] - frozen.samples.tau)) > 1e-6
