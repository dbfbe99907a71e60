"""A law's internal state: kept by ControlLaw, carried by the compiled dispatch and loop, reset on demand.

The thesis laws have none (their state is ``(0, n)``); super-twisting and integral sliding mode
integrate one float per joint with the control period ``h``.
"""

from __future__ import annotations

import numpy as np
import pytest

from pdsmc_ros.control import ControlLaw, law
from pdsmc_ros.errors import InvalidInputError
from pdsmc_ros.runs.builder import make_run
from pdsmc_ros.sim import PlantStepper
from pdsmc_ros.sim.loop import run_loop
from pdsmc_ros.sim.simulator import _reference_samples


@pytest.mark.parametrize("controller", ["pd", "smc", "pdsmc", "pdg", "ctc"])
def test_stateless_laws_keep_no_state(controller: str) -> None:
    spec = make_run("parallel_5r", "circle", controller)
    control = ControlLaw.from_spec(spec)
    assert law(controller).state_size == 0 and control.state.shape == (0, 2)
    assert control.h == 1.0 / spec.rate


@pytest.mark.parametrize("controller", ["sta", "ismc"])
def test_a_stateful_law_starts_at_zero_and_resets(controller: str) -> None:
    spec = make_run("parallel_5r", "circle", controller)
    control = ControlLaw.from_spec(spec)
    assert control.state.shape == (1, 2) and not control.state.any()
    ref = spec.reference().sample([0.3])
    q = ref.q[0] + np.array([1e-3, -2e-3])
    first = control.torque(q, ref.qd[0], ref.q[0], ref.qd[0], ref.qdd[0])
    assert control.state.any()
    second = control.torque(q, ref.qd[0], ref.q[0], ref.qd[0], ref.qdd[0])
    assert not np.array_equal(first, second)  # the state entered the torque
    assert np.array_equal(control.reset().state, np.zeros((1, 2)))
    assert np.array_equal(control.torque(q, ref.qd[0], ref.q[0], ref.qd[0], ref.qdd[0]), first)
    control.warm_up(q, ref.qd[0])
    assert not control.state.any()  # warming up leaves no state behind
    with pytest.raises(InvalidInputError, match="its period h must be > 0 s"):
        ControlLaw(controller, spec.gains.matrix(), spec.smc_model_vector(), spec.nominal_model())


@pytest.mark.parametrize("controller", ["sta", "ismc"])
@pytest.mark.parametrize("robot", ["serial_3r", "parallel_5r"])
def test_the_compiled_loop_carries_the_state_as_the_calls_do(controller: str, robot: str) -> None:
    """The compiled closed loop (state and h as arguments) and the loop of ControlLaw.torque calls
    (the controller node's path) give the same run to 1e-12, and leave the same final state."""
    spec = make_run(robot, "circle", controller, rate=2000.0 if robot == "serial_3r" else None)
    _, refs = _reference_samples(spec)
    refs = refs[:2001]
    plant, h = spec.robot_model(), 1.0 / spec.rate
    q0 = refs[0, 0] + 2e-3
    in_loop = ControlLaw.from_spec(spec)
    by_calls = ControlLaw.from_spec(spec)
    a = run_loop(plant, in_loop, q0, refs, h, 10)
    # the nodes' path: one ControlLaw.torque call and one PlantStepper step per period
    stepper = PlantStepper(plant, h, q0, np.zeros(plant.n))
    b: list[list[np.ndarray]] = [[], [], []]
    for k in range(refs.shape[0]):
        tau = by_calls.torque(stepper.q, stepper.qd, refs[k, 0], refs[k, 1], refs[k, 2])
        if k % 10 == 0:
            for out, x in zip(b, (stepper.q, stepper.qd, tau), strict=True):
                out.append(x.copy())
        if k < refs.shape[0] - 1:
            stepper.step(tau)
    assert in_loop.state.any()
    np.testing.assert_allclose(in_loop.state, by_calls.state, rtol=1e-12, atol=1e-12)
    for x, y in zip(a[:3], b, strict=True):
        np.testing.assert_allclose(x, np.array(y), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("controller", ["pd", "pdsmc", "ctc", "sta", "ismc", "pdsmc_pos"])
def test_other_gains_at_run_time_give_the_law_a_fresh_build_gives_and_carry_its_state(controller: str) -> None:
    """:meth:`ControlLaw.with_gains` (a gain change at run time, without rebuilding the model): the
    torque of :meth:`ControlLaw.from_spec` with those gains, bit for bit, from the state reached so far."""
    import dataclasses

    spec = make_run("ur5", "circle", controller)
    ref = spec.reference().sample([0.2, 0.4])
    q = ref.q[0] + np.linspace(-2e-3, 3e-3, 6)
    running = ControlLaw.from_spec(spec)
    running.torque(q, ref.qd[0], ref.q[0], ref.qd[0], ref.qdd[0])  # a state to carry (stateful laws)
    other = dataclasses.replace(spec, gains=spec.gains.scaled({name: 1.3 for name, _ in spec.gains.rows}))
    changed = running.with_gains(other.gains.matrix())
    fresh = ControlLaw.from_spec(other)
    fresh.state[:] = running.state
    args = (q, ref.qd[1], ref.q[1], ref.qd[1], ref.qdd[1])
    assert np.array_equal(changed.torque(*args), fresh.torque(*args))
    assert not np.array_equal(changed.torque(*args), running.torque(*args))
    assert changed.state is not running.state  # the running law's own state untouched by the new one's calls


def test_other_gains_of_another_shape_are_refused() -> None:
    control = ControlLaw.from_spec(make_run("parallel_5r", "circle", "pd"))
    with pytest.raises(InvalidInputError, match="gains must be a finite"):
        control.with_gains(np.ones((5, 3)))
    with pytest.raises(InvalidInputError, match="gains must be a finite"):
        control.with_gains(np.full(control.gains.shape, np.nan))
