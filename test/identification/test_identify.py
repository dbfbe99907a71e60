"""The identification end to end: through the signal chain at a recording's rate, from bags of the
project's own simulator through ``pdsmc identify``, the identified arm fed back with ``--model``,
and every bad input refused in one line with nothing written."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

pin = pytest.importorskip("pinocchio")
pytest.importorskip("clarabel")

from pdsmc_ros.cli import main  # noqa: E402
from pdsmc_ros.identification.excitation import (  # noqa: E402
    FourierExcitation,
    RestBasis,
    excitation_limits,
    largest_scale,
)
from pdsmc_ros.identification.identify import identify  # noqa: E402
from pdsmc_ros.identification.model import ArmDynamics, arm_of  # noqa: E402
from pdsmc_ros.identification.simulated import simulate_excitation, write_joint_states  # noqa: E402
from pdsmc_ros.robots.catalog import example_robot_data_dir, resolve_robot  # noqa: E402
from pdsmc_ros.robots.registry import make_robot  # noqa: E402

PERIOD = 8.0


def excitation_of(dynamics: ArmDynamics, seed: int = 0) -> FourierExcitation:
    """A random excitation scaled into the limits (no search: these tests need a motion, not the best)."""
    rng = np.random.default_rng(seed)
    basis = RestBasis(dynamics.n, 5)
    a, b = basis.coefficients(rng.normal(size=basis.size))
    shape = FourierExcitation(np.asarray(dynamics.arm.home, dtype=float), a, b, PERIOD)
    limits = excitation_limits(dynamics, excursion=0.6)
    return shape.scaled(largest_scale(shape, limits, dynamics, np.arange(400) * PERIOD / 400))


@pytest.fixture(scope="module")
def ur5() -> ArmDynamics:
    return ArmDynamics(arm_of("ur5"))


def test_coulomb_friction_through_the_filters(ur5: ArmDynamics) -> None:
    """Exact efforts at 1 kHz with Coulomb friction and a payload, through the whole signal chain: the
    filtered regressor keeps the equation, so payload and frictions come out within a fraction of a
    per cent (filtering the efforts alone missed them by 5-40 %: pdsmc_ros/identification/signals.py)."""
    layout = ur5.layout
    truth = ur5.nominal.copy()
    truth[layout.payload] = pin.Inertia(2.0, np.array([0.0, 0.01, 0.05]), np.zeros((3, 3))).toDynamicParameters()
    truth[layout.joint_field("armature")] = [0.3, 0.3, 0.2, 0.05, 0.05, 0.05]
    truth[layout.joint_field("friction_coulomb")] = [5.0, 7.0, 4.0, 1.2, 1.0, 0.6]
    truth[layout.joint_field("friction_viscous")] = [2.0, 3.0, 1.5, 0.4, 0.35, 0.25]
    t = np.arange(0.0, 3 * PERIOD, 0.001)
    q, qd, qdd = excitation_of(ur5).sample(t)
    result = identify(ur5, t, q, ur5.consistent_torque(truth, q, qd, qdd))
    values = result.fit.values
    assert values[layout.payload.start] == pytest.approx(2.0, rel=5e-3)
    for field, tolerance in (("friction_coulomb", 0.01), ("friction_viscous", 0.02)):
        part = layout.joint_field(field)
        np.testing.assert_allclose(values[part], truth[part], rtol=tolerance, err_msg=field)
    assert np.all(result.nrmse < 0.005)
    assert result.prepared.cutoff == pytest.approx(5 * 5 / PERIOD, rel=0.1)


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A 'true' UR5 (its URDF, a 1.5 kg tool, motor inertia and viscous friction in its options) run
    through an excitation by the project's simulator under computed torque with the URDF's model:
    a training bag of four periods and a held-out bag of two, from another phase."""
    where = tmp_path_factory.mktemp("identify")
    shutil.copy(example_robot_data_dir() / "ur_description/urdf/ur5_robot.urdf", where / "truth.urdf")
    truth = {"ee_frame": "tool0", "home": [0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0], "payload_mass": 1.5,
             "payload_com": [0.0, 0.02, 0.06], "armature": [0.4, 0.4, 0.3, 0.05, 0.05, 0.05],
             "friction_viscous": [2.0, 3.0, 1.5, 0.4, 0.35, 0.25]}
    (where / "truth.yaml").write_text(yaml.safe_dump(truth))
    plant = make_robot(resolve_robot(str(where / "truth.urdf")))
    model = make_robot(resolve_robot("ur5"))
    excitation = excitation_of(ArmDynamics(model.arm), seed=1)
    for name, periods, start in (("train", 4, 0.0), ("held_out", 2, 0.37 * PERIOD)):
        run = simulate_excitation(plant, model, excitation, periods=periods, start=start)
        write_joint_states(where / name, plant.joint_names, run.t, run.q, run.qd, run.tau)
    return {"dir": where, "train": where / "train", "held_out": where / "held_out", "truth": where / "truth.urdf"}


def test_identify_a_simulated_run(simulated: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    out = simulated["dir"] / "identified"
    code = main(["identify", str(simulated["train"]), "--robot", "ur5", "--out", str(out),
                 "--validate", str(simulated["held_out"])])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "base regressor condition number" in printed.out
    for name in ("identified.urdf", "identified.yaml", "identification.yaml", "torques.png"):
        assert (out / name).is_file()
    options = yaml.safe_load((out / "identified.yaml").read_text())
    assert options["payload_mass"] == pytest.approx(1.5, rel=0.01)
    np.testing.assert_allclose(options["payload_com"], [0.0, 0.02, 0.06], atol=3e-3)
    np.testing.assert_allclose(options["friction_viscous"], [2.0, 3.0, 1.5, 0.4, 0.35, 0.25], rtol=0.03)
    np.testing.assert_allclose(options["armature"], [0.4, 0.4, 0.3, 0.05, 0.05, 0.05], rtol=0.1)
    np.testing.assert_allclose(options["friction_coulomb"], 0.0, atol=0.02)  # the simulator has none
    report = yaml.safe_load((out / "identification.yaml").read_text())
    assert max(report["nrmse"]["validation"].values()) < 0.01
    assert min(report["nrmse"]["nominal_on_validation"].values()) > 0.05  # the URDF alone: far off
    assert report["filter"]["cutoff_hz"] == pytest.approx(5 * 5 / PERIOD, rel=0.1)
    # the identified arm is an arm like any: its model is the fitted parameters
    fitted = np.array([p["value"] for p in report["standard_parameters"]])
    identified = ArmDynamics(arm_of(str(out / "identified.urdf")))
    rng = np.random.default_rng(0)
    q, qd, qdd = rng.normal(size=(3, 10, 6))
    np.testing.assert_allclose(identified.torque(identified.nominal, q, qd, qdd),
                               ArmDynamics(arm_of("ur5")).torque(fitted, q, qd, qdd), atol=1e-5)


def test_a_window_of_the_bag(simulated: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    """``--window`` fits only the states in it (a recording holds the arm at rest, braked, the
    goal's lead besides the excitation): three of the four periods, the payload still found."""
    out = simulated["dir"] / "windowed"
    code = main(["identify", str(simulated["train"]), "--robot", "ur5", "--out", str(out), "--window", "0:24",
                 "--validate", str(simulated["held_out"]), "--validate-window", "2:14"])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert re.search(r"joint states over 24 s", printed.out), printed.out
    assert yaml.safe_load((out / "identified.yaml").read_text())["payload_mass"] == pytest.approx(1.5, rel=0.02)


def test_the_identified_model_fed_back_to_computed_torque(simulated: dict[str, Path],
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """Computed torque on the true arm: with the URDF's model the tool pulls it millimetres off the
    contour; with the identified one (--model) it tracks as with the true model."""
    out = simulated["dir"] / "fed_back"
    assert main(["identify", str(simulated["train"]), "--robot", "ur5", "--out", str(out)]) == 0
    errors = {}
    for label, model in (("urdf", "ur5"), ("identified", str(out / "identified.yaml")),
                         ("true", str(simulated["truth"]))):
        capsys.readouterr()
        assert main(["simulate", "--robot", str(simulated["truth"]), "--contour", "circle", "--controller", "ctc",
                     "--gain", "omega_n=30", "--gain", "zeta=1", "--smc-reading", "exact", "--model", model,
                     "--json"]) == 0
        errors[label] = yaml.safe_load(capsys.readouterr().out)["contour_mean"]
    assert errors["identified"] < errors["urdf"] / 100.0, errors
    assert errors["identified"] < 10.0 * errors["true"] + 1e-6, errors
    # check-gains and a run's description take it too (the description round-trips it: bags, nodes)
    capsys.readouterr()
    assert main(["check-gains", "--robot", "ur5", "--contour", "circle", "--controller", "ctc", "--gain",
                 "omega_n=30", "--gain", "zeta=1", "--model", str(out / "identified.yaml")]) == 0
    from pdsmc_ros.runs.builder import RunSpec, make_run

    spec = make_run("ur5", "circle", "ctc", gains=None, overrides={"omega_n": [30.0], "zeta": [1.0]},
                    model=str(out / "identified.yaml"))
    again = RunSpec.from_description(spec.describe())
    assert again.model == spec.model
    np.testing.assert_allclose(again.nominal_model().arm.armature, yaml.safe_load(
        (out / "identified.yaml").read_text())["armature"])
    assert main(["simulate", "--robot", "ur5", "--contour", "circle", "--controller", "ctc", "--model", "panda"]) == 2
    assert "a model of this arm has its joints" in capsys.readouterr().err


def joint_states(where: Path, name: str, dynamics: ArmDynamics, *, seconds: float = 24.0, efforts: bool = True,
                 frozen: int | None = None, joints: tuple[str, ...] | None = None) -> Path:
    t = np.arange(0.0, seconds, 0.002)
    q, qd, qdd = excitation_of(dynamics).sample(t)
    if frozen is not None:
        q[:, frozen], qd[:, frozen], qdd[:, frozen] = q[0, frozen], 0.0, 0.0
    tau = dynamics.torque(dynamics.nominal, q, qd, qdd)
    write_joint_states(where / name, joints or dynamics.layout.joint_names, t, q, qd, tau, efforts=efforts)
    return where / name


@pytest.fixture(scope="module")
def bad_bags(tmp_path_factory: pytest.TempPathFactory, ur5: ArmDynamics) -> dict[str, Path]:
    where = tmp_path_factory.mktemp("bad")
    renamed = tuple(f"other_{j}" for j in ur5.layout.joint_names)
    partial = (*ur5.layout.joint_names[:5], "gripper_joint")
    return {
        "no_efforts": joint_states(where, "no_efforts", ur5, efforts=False),
        "short": joint_states(where, "short", ur5, seconds=3.0),
        # long enough for the fit's equations with the dead zone's guard: the still joint is what it finds
        "still_joint": joint_states(where, "still_joint", ur5, seconds=32.0, frozen=0),
        "missing": joint_states(where, "missing", ur5, joints=partial),
        "another_arm": joint_states(where, "another_arm", ur5, joints=renamed),
    }


@pytest.mark.parametrize(("bag", "robot", "message"), [
    ("no_efforts", "ur5", r"carry no efforts"),
    ("short", "ur5", r"run too short|shorter than the filter"),
    ("still_joint", "ur5", (r"not exciting enough: .* not identifiable: .*shoulder_pan_joint.* -- joint\(s\) "
                            r"shoulder_pan_joint did not move")),
    ("missing", "ur5", r"joints missing from the bag's /joint_states: wrist_3_joint"),
    ("another_arm", "ur5", r"the arm does not match the bag's joints"),
    ("missing", "panda", r"the arm does not match the bag's joints"),
    ("nowhere", "ur5", r"no such file or directory"),
    ("still_joint", "ur5 --window 40:50", r"the window 40-50 s holds 0 joint states"),
    ("still_joint", "ur5 --window 5", r"--window must be START:END"),
])
def test_bad_input_is_one_line_exit_2_and_nothing_written(bad_bags: dict[str, Path], tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str], bag: str, robot: str,
                                                          message: str) -> None:
    out = tmp_path / "out"
    path = bad_bags.get(bag, tmp_path / "nowhere")
    code = main(["identify", str(path), "--robot", *robot.split(), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("pdsmc identify: error: "), err
    assert re.search(message, err[0]), err[0]
    assert not out.exists()


def test_a_held_out_bag_of_another_arm_is_refused_before_anything_is_written(bad_bags: dict[str, Path],
                                                                             tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["identify", str(bad_bags["still_joint"]), "--robot", "ur5", "--out", str(out), "--validate",
                 str(bad_bags["another_arm"])]) == 2
    assert not out.exists()
