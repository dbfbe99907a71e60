"""A run that keeps no samples (simulate(keep_samples=False), sim/stretches.py): the same loop in
stretches, the same statistics and scores as the run that keeps them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate, stretches


@pytest.mark.parametrize(("robot", "controller"), [("serial_3r", "pdsmc"), ("parallel_5r", "sta"),
                                                   ("ur5", "smc")])
def test_the_statistics_equal_the_kept_runs_to_the_last_digit(robot: str, controller: str,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    spec = make_run(robot, "circle", controller)
    full = simulate(spec)
    # short stretches, none a divisor of the run: the carried state, law state and step count are used
    monkeypatch.setattr(stretches, "STRETCH_STEPS", 997 * spec.sample_every + 3)
    lean = simulate(spec, keep_samples=False)
    assert lean.steps == full.steps and len(lean.samples.t) == 0
    assert lean.metrics.as_dict() == full.metrics.as_dict()


def test_a_diverging_run_stops_in_its_stretch_with_the_same_reason() -> None:
    spec = dataclasses.replace(make_run("serial_3r", "circle", "pd", rate=500.0), enforce_limits=False)
    full = simulate(spec, check_stability=False)
    lean = simulate(spec, check_stability=False, keep_samples=False)
    assert full.diverged and lean.diverged == full.diverged
    assert np.isnan(lean.metrics.contour_mean) and np.isnan(full.metrics.contour_mean)
    assert lean.metrics.saturated_periods == full.metrics.saturated_periods
