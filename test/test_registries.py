"""A new robot and a new control law from this file alone: registered, then run by the simulator.

Neither has a compiled form, so the simulator runs them behind their Python forms
(robots.python_form, control.python_form), in the loop every run goes through; a law written
in Python is proven equal to the compiled one on a thesis run in test/control/test_laws.py.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from pdsmc_ros.control import (
    ControlLaw,
    Gains,
    LawEntry,
    LawSetup,
    law,
    law_names,
    register_law,
    unregister_law,
)
from pdsmc_ros.control.laws import pd_linear_gains
from pdsmc_ros.errors import ConfigError
from pdsmc_ros.robots import (
    Manipulator,
    PlanarChain,
    RobotParams,
    make_robot,
    register_robot,
    robot_names,
    unregister_robot,
)
from pdsmc_ros.robots.base import FloatArray, diag
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate

TOY_CONFIG = {
    "links": [{"mass": 1.2, "length": 0.4, "com": 0.2, "inertia": 0.02},
              {"mass": 0.8, "length": 0.3, "com": 0.15, "inertia": 0.01}],
    "motor_inertia": 0.02,
    "motor_damping": 0.05,
    "control_rate": 2000.0,
    "sample_rate": 500.0,
    "contour_bound": 1e-3,
}


class Toy2R(Manipulator):
    """A planar 2R arm (x, y task point), numpy only: no compiled form."""

    name = "toy_2r"
    n = 2
    task_dim = 2
    joint_names = ("shoulder", "elbow")
    payload_link = 1

    def __init__(self, payload: float = 0.0, *, params: RobotParams) -> None:
        super().__init__(payload, params=params)
        self.chain = PlanarChain(params.links, tip_mass=payload, gravity=params.gravity)

    def _fk(self, q: FloatArray) -> FloatArray:
        return self.chain.tip(q)

    def _ik(self, p: FloatArray) -> FloatArray:
        l1, l2 = self.chain.lengths
        c2 = (p[..., 0] ** 2 + p[..., 1] ** 2 - l1 * l1 - l2 * l2) / (2 * l1 * l2)
        q2 = np.arccos(np.clip(c2, -1.0, 1.0))
        q1 = np.arctan2(p[..., 1], p[..., 0]) - np.arctan2(l2 * np.sin(q2), l1 + l2 * np.cos(q2))
        return np.stack([q1, q2], axis=-1)

    def reachable(self, p: FloatArray) -> np.ndarray:
        l1, l2 = self.chain.lengths
        d = np.hypot(p[..., 0], p[..., 1])
        return (d > abs(l1 - l2) + 1e-3) & (d < l1 + l2 - 1e-3)

    def _jacobian(self, q: FloatArray) -> FloatArray:
        return self.chain.tip_jacobian(q)

    def joint_rates(self, q: FloatArray, pd: FloatArray, pdd: FloatArray) -> tuple[FloatArray, FloatArray]:
        jac = self._jacobian(q)
        qd = np.linalg.solve(jac, pd[..., None])[..., 0]
        jdot = self.chain.tip_jacobian_dot(q, qd)
        qdd = np.linalg.solve(jac, (pdd - np.einsum("...ij,...j->...i", jdot, qd))[..., None])[..., 0]
        return qd, qdd

    def _mass_matrix(self, q: FloatArray) -> FloatArray:
        return self.chain.mass_matrix(q) + diag(self.J)

    def _coriolis_matrix(self, q: FloatArray, qd: FloatArray) -> FloatArray:
        return self.chain.coriolis_matrix(q, qd)

    def _gravity(self, q: FloatArray) -> FloatArray:
        return self.chain.gravity_vector(q)

    def _potential(self, q: FloatArray) -> FloatArray:
        return self.chain.potential_energy(q)


def pd_gravity_torque(setup: LawSetup, q: FloatArray, qd: FloatArray, q_ref: FloatArray, qd_ref: FloatArray,
                      qdd_ref: FloatArray) -> FloatArray:
    """PD with gravity compensation from the nominal model (not a thesis law)."""
    g = setup.gains
    return g[0] * (q_ref - q) + g[1] * (qd_ref - qd) + setup.model.gravity(q)


@pytest.fixture
def toys() -> Iterator[None]:
    register_robot(Toy2R, config=TOY_CONFIG)
    register_law(LawEntry("pd_gravity", "PD+G", ("kp", "kd"), pd_gravity_torque, "a test's own law",
                          linear_gains=pd_linear_gains))
    yield
    unregister_robot("toy_2r")
    unregister_law("pd_gravity")


def test_a_toy_robot_and_law_registered_here_run_in_the_simulator(toys: None, tmp_path: Path) -> None:  # noqa: ARG001
    assert "toy_2r" in robot_names() and "pd_gravity" in law_names()
    waypoints = tmp_path / "square.csv"
    waypoints.write_text("x,y\n0.45,0.05\n0.45,0.15\n0.35,0.15\n0.35,0.05\n0.45,0.05\n")
    gains = Gains.from_mapping({"kp": [400, 200], "kd": [40, 20]}, 2, "pd_gravity")
    spec = make_run("toy_2r", "csv", "pd_gravity", gains=gains, waypoints_file=str(waypoints), segment_duration=0.5)
    assert spec.rate == 2000.0 and spec.bound == 1e-3  # the robot's own settings
    result = simulate(spec)
    assert result.steps == 4000  # four 0.5 s segments at 2 kHz
    contour_mean = result.metrics.contour_mean
    assert np.isfinite(contour_mean) and 0.0 < contour_mean < 5e-3
    # gravity compensation is what holds the arm: without it the same PD sags far more
    register_law(LawEntry("pd_plain", "PD", ("kp", "kd"),
                          lambda s, q, qd, qr, qdr, qddr: s.gains[0] * (qr - q) + s.gains[1] * (qdr - qd)))
    try:
        sagging = simulate(make_run("toy_2r", "csv", "pd_plain", gains=gains, waypoints_file=str(waypoints),
                                    segment_duration=0.5), check_stability=False)
    finally:
        unregister_law("pd_plain")
    assert sagging.metrics.contour_mean > 3 * contour_mean


def test_a_compiled_law_runs_a_robot_written_in_numpy(toys: None, tmp_path: Path) -> None:  # noqa: ARG001
    """The compiled PD+G on the toy arm (its gravity read back from numpy through robots.python_form)
    runs as this file's own PD+G written in Python."""
    waypoints = tmp_path / "square.csv"
    waypoints.write_text("x,y\n0.45,0.05\n0.45,0.15\n0.35,0.15\n0.35,0.05\n0.45,0.05\n")
    exact = {"gravity": 1.0, "at_desired": 0.0}
    gains = {"kp": [400, 200], "kd": [40, 20]}
    runs = [simulate(make_run("toy_2r", "csv", name, gains=Gains.from_mapping(gains, 2, name), smc_model=exact,
                              waypoints_file=str(waypoints), segment_duration=0.5))
            for name in ("pdg", "pd_gravity")]
    assert ControlLaw.from_spec(runs[0].spec).code < 1000 <= ControlLaw.from_spec(runs[1].spec).code
    np.testing.assert_allclose(runs[0].samples.q, runs[1].samples.q, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(runs[0].samples.tau, runs[1].samples.tau, rtol=1e-12, atol=1e-9)


def test_unknown_and_duplicate_names_are_refused(toys: None) -> None:  # noqa: ARG001
    with pytest.raises(ConfigError, match="unknown robot 'nope'; choose one of: serial_3r, parallel_5r, .*toy_2r"):
        make_robot("nope")
    with pytest.raises(ConfigError, match="unknown controller 'nope'"):
        law("nope")

    class Other(Toy2R):
        pass

    with pytest.raises(ValueError, match="already registered"):
        register_robot(Other)
    with pytest.raises(ValueError, match="already registered"):
        register_law(LawEntry("pd_gravity", "X", ("kp",), pd_gravity_torque))
    with pytest.raises(ConfigError, match="no pd gains for toy_2r"):
        make_run("toy_2r", "csv", "pd", waypoints_file="unused.csv")
