"""The compiled robot dispatch (robots/compiled.py): made from one table, an unknown code is an error."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

from pdsmc_ros.robots import compiled, make_robot
from pdsmc_ros.robots.catalog import resolve_robot
from pdsmc_ros.runs.builder import make_run

UNKNOWN = 99
N = 3


def _arguments() -> dict[str, tuple[object, ...]]:
    p = make_robot("serial_3r").pack()
    q = np.zeros(N)
    work = compiled.workspace(N)
    return {
        "terms": (p, q, q, np.zeros((N, N)), np.zeros(N), work),
        "coriolis_times": (p, q, q, q, np.zeros(N), work),
        "gravity": (p, q, np.zeros(N), work),
        "damping": (p, 0),
        "motor_inertia": (p, 0),
        "outputs": (p, q, q, np.zeros(compiled.OUTPUTS_SIZE), work),
        "forward_dynamics": (p, q, q, q, np.zeros(N), work),
        "model_terms": (p, q, q, q, np.zeros((N, N)), np.zeros(N), np.zeros(N), work),
    }


@pytest.mark.parametrize("function", sorted(_arguments()))
def test_an_unknown_robot_code_raises_in_every_dispatcher(function: str) -> None:
    args = _arguments()[function]
    dispatcher = getattr(compiled, function)
    dispatcher(0, *args)  # a known code (the serial arm's) runs
    with pytest.raises(ValueError, match="unknown robot code"):
        dispatcher(UNKNOWN, *args)


def test_a_known_code_gets_its_own_robots_parameters() -> None:
    """The serial arm's B and J, not another robot's (the fall-through this table replaced)."""
    robot = make_robot("serial_3r")
    kind, p = compiled.pack(robot)
    for i in range(robot.n):
        assert compiled.damping(kind, p, i) == robot.B[i]
        assert compiled.motor_inertia(kind, p, i) == robot.J[i]


def test_every_table_entry_names_compiled_functions_of_one_signature() -> None:
    for code, entry in compiled.COMPILED.items():
        assert isinstance(code, int) and entry.joints >= 0
        for field in ("terms", "accelerations", "coriolis_times", "gravity", "damping", "motor_inertia", "outputs",
                      "model_terms"):
            assert hasattr(getattr(entry, field), "py_func"), (code, field)


def test_an_unknown_constant_code_fails_to_compile() -> None:
    @njit
    def accelerate(p, q, out, work):  # noqa: ANN001, ANN202
        compiled.accelerations(UNKNOWN, p, q, q, q, out, work)

    args = _arguments()["forward_dynamics"]
    with pytest.raises(TypingError, match="robot code"):
        accelerate(args[0], args[1], args[4], args[5])


def test_pack_refuses_a_code_without_an_entry() -> None:
    robot = make_robot("serial_3r")
    robot.kernel = UNKNOWN  # type: ignore[misc]
    with pytest.raises(TypeError, match="no entry"):
        compiled.pack(robot)


@pytest.mark.parametrize("robot_name", ["serial_3r", "parallel_5r", "ur5"])
def test_model_terms_are_the_three_functions_floats_bit_for_bit(robot_name: str) -> None:
    """``model_terms`` (one call, the five-bar's loop closure solved once) gives exactly what ``terms``,
    ``gravity`` and ``coriolis_times`` give apart, at states all over the joint space."""
    robot = make_robot(resolve_robot(robot_name))
    kind, p = compiled.pack(robot)
    n = robot.n
    rng = np.random.default_rng(7)
    home = make_run(robot_name, "circle", "pd").reference().sample(np.zeros(1)).q[0]  # inside the workspace
    work = compiled.workspace(n)
    checked = 0
    for _ in range(200):
        q = home + rng.uniform(-0.4, 0.4, n)
        qd, v = rng.normal(0.0, 2.0, n), rng.normal(0.0, 2.0, n)
        mass, bias, grav, cor = np.zeros((n, n)), np.zeros(n), np.zeros(n), np.zeros(n)
        compiled.terms(kind, p, q, qd, mass, bias, work)
        compiled.gravity(kind, p, q, grav, work)
        compiled.coriolis_times(kind, p, q, qd, v, cor, work)
        if not (np.all(np.isfinite(mass)) and np.all(np.isfinite(cor))):
            continue  # a five-bar draw outside its workspace: nothing to compare
        fused = np.full((n, n), np.nan), np.full(n, np.nan), np.full(n, np.nan)
        compiled.model_terms(kind, p, q, qd, v, *fused, work)
        for apart, together in zip((mass, grav, cor), fused, strict=True):
            assert np.array_equal(apart, together), robot_name
        checked += 1
    assert checked >= 150
