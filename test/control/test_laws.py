"""The thesis laws, written once and compiled, against their equations read in numpy; a law and a
robot written in Python run in the same loop (behind the compiled dispatch)."""

from __future__ import annotations

import numpy as np
import pytest
from law_readings import pdsmc_reading, smc_reading

from pdsmc_ros.control import ControlLaw, LawEntry, LawSetup, register_law, unregister_law
from pdsmc_ros.control.laws import pdsmc_linear_gains
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import simulate


@pytest.mark.parametrize("robot", ["serial_3r", "parallel_5r", "ur5"])
@pytest.mark.parametrize("reading", [{"at_desired": 1.0, "motor_inertia": 0.0},
                                     {"mass": 1.0, "coriolis": 0.5, "gravity": 1.0, "damping": 0.0}])
def test_the_smc_is_eq_3_15_under_every_model_reading(robot: str, reading: dict[str, float]) -> None:
    """The SMC's model estimate read otherwise than the default (test_simulation holds the three laws
    to their equations under it), on the thesis arms and a URDF arm."""
    spec = make_run(robot, "circle", "smc", smc_model=reading)
    control = ControlLaw.from_spec(spec)
    setup = LawSetup(spec.gains.matrix(), spec.nominal_model(), spec.smc_model_vector())
    rng = np.random.default_rng(5)
    ref = spec.reference().sample(rng.uniform(0, 5, 20))
    n = spec.robot_model().n
    for k in range(20):
        q = ref.q[k] + rng.normal(0, 2e-3, n)
        qd = ref.qd[k] + rng.normal(0, 2e-2, n)
        args = (q, qd, ref.q[k], ref.qd[k], ref.qdd[k])
        expected = smc_reading(setup, *args)
        assert np.allclose(control.torque(*args), expected, rtol=1e-12, atol=1e-10 * np.max(np.abs(expected)))


def test_a_law_written_in_python_runs_a_thesis_run_as_the_compiled_one() -> None:
    """PD-SMC registered as a Python torque (behind control.python_form): the whole serial circle run
    agrees with the compiled law's to 1e-9."""
    register_law(LawEntry("pdsmc_python", "PD-SMC (Python)", ("kp", "kd", "ks", "lam", "phi"), pdsmc_reading,
                          linear_gains=pdsmc_linear_gains))
    try:
        base = make_run("serial_3r", "circle", "pdsmc")
        compiled = simulate(base)
        python_run = simulate(make_run("serial_3r", "circle", "pdsmc_python", gains=base.gains))
        assert ControlLaw.from_spec(python_run.spec).code >= 1000  # ran behind the Python form
    finally:
        unregister_law("pdsmc_python")
    assert np.max(np.abs(python_run.samples.q - compiled.samples.q)) < 1e-9
    assert np.max(np.abs(python_run.samples.tau - compiled.samples.tau)) < 1e-6


def test_a_law_gives_either_its_code_or_its_python_torque() -> None:
    with pytest.raises(ValueError, match="either its compiled form's code or its Python torque"):
        LawEntry("neither", "N", ("kp",))
    with pytest.raises(ValueError, match="either its compiled form's code or its Python torque"):
        LawEntry("both", "B", ("kp",), pdsmc_reading, code=2)


def test_a_law_written_in_python_takes_other_gains_at_run_time() -> None:
    """:meth:`ControlLaw.with_gains` on a Python law: the new law's torque is its own gains' (its
    code calls back the new law, not the one it came from)."""
    register_law(LawEntry("pdsmc_python", "PD-SMC (Python)", ("kp", "kd", "ks", "lam", "phi"), pdsmc_reading,
                          linear_gains=pdsmc_linear_gains))
    try:
        spec = make_run("serial_3r", "circle", "pdsmc_python", gains=make_run("serial_3r", "circle", "pdsmc").gains)
        running = ControlLaw.from_spec(spec)
        gains = running.gains * 1.5
        changed = running.with_gains(gains)
        ref = spec.reference().sample([0.5])
        args = (ref.q[0] + 1e-2, ref.qd[0], ref.q[0], ref.qd[0], ref.qdd[0])
        expected = pdsmc_reading(LawSetup(gains, running.setup.model, running.smc_model), *args)
        assert changed.code != running.code
        assert np.allclose(changed.torque(*args), expected, rtol=1e-12, atol=1e-12)
        assert not np.allclose(running.torque(*args), expected)
    finally:
        unregister_law("pdsmc_python")
