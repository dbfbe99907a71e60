"""Super-twisting and integral sliding mode: their equations, their states' integration, their presets."""

from __future__ import annotations

import numpy as np
import pytest
from law_inputs import states

from pdsmc_ros.config import load_config
from pdsmc_ros.contours.presets import contour_set
from pdsmc_ros.control import ControlLaw, law
from pdsmc_ros.control.stability import check_gains, effective_gains
from pdsmc_ros.errors import MissingGainsError
from pdsmc_ros.robots import robot_names
from pdsmc_ros.robots.catalog import catalog
from pdsmc_ros.runs.builder import make_run, preset_gains
from pdsmc_ros.sim import simulate

ROBOT_CONTOURS = [("serial_3r", "circle"), ("parallel_5r", "circle"), ("ur5", "circle")]


def _preset_robot_contours() -> list[tuple[str, str]]:
    """Every registered robot and named URDF arm with SMC presets, on each of its preset contours."""
    out = []
    for robot in (*robot_names(), *(name for name in catalog() if name not in robot_names())):
        for contour in load_config("contours").get(contour_set(robot)) or ():
            try:
                preset_gains(robot, contour, "smc")
            except MissingGainsError:
                continue
            out.append((robot, contour))
    return out


def _model_part(spec, q, qd, a, v):  # noqa: ANN001, ANN202
    """The SMC's model terms (Eq. 3.15) with the numpy model: s_M Mbar a + s_C C v + s_G G + s_B B v."""
    model, s = spec.nominal_model(), spec.smc_model_vector()
    return (s[0] * model.mass_matrix(q) @ a + s[1] * model.coriolis_matrix(q, qd) @ v + s[2] * model.gravity(q)
            + s[3] * model.B * v)


@pytest.mark.parametrize(("robot", "contour"), ROBOT_CONTOURS)
def test_sta_follows_its_equation_and_its_state_integrates_k2_sign_s(robot: str, contour: str) -> None:
    spec = make_run(robot, contour, "sta", smc_model={"damping": 1.0})
    control = ControlLaw.from_spec(spec)
    k1, k2, lam = (np.array(spec.gains[k]) for k in ("k1", "k2", "lam"))
    v = np.zeros(spec.robot_model().n)
    for q, qd, q_ref, qd_ref, qdd_ref in states(spec, 12, 8):
        e, ed = q_ref - q, qd_ref - qd
        s = lam * e + ed
        expected = (_model_part(spec, q, qd, qdd_ref + lam * ed, qd_ref + lam * e)
                    + k1 * np.sqrt(np.abs(s)) * np.sign(s) + v)
        np.testing.assert_allclose(control.torque(q, qd, q_ref, qd_ref, qdd_ref), expected, rtol=1e-12, atol=1e-9)
        v = v + control.h * k2 * np.sign(s)  # the state after the call: v + h k2 sign(s)
        np.testing.assert_allclose(control.state[0], v, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize(("robot", "contour"), ROBOT_CONTOURS)
def test_ismc_follows_its_equation_and_its_state_integrates_e(robot: str, contour: str) -> None:
    spec = make_run(robot, contour, "ismc")
    control = ControlLaw.from_spec(spec)
    ks, lam, phi = (np.array(spec.gains[k]) for k in ("ks", "lam", "phi"))
    z = np.zeros(spec.robot_model().n)
    for q, qd, q_ref, qd_ref, qdd_ref in states(spec, 12, 9):
        e, ed = q_ref - q, qd_ref - qd
        qd_r = qd_ref + 2 * lam * e + lam**2 * z
        expected = (_model_part(spec, q, qd, qdd_ref + 2 * lam * ed + lam**2 * e, qd_r)
                    + ks * np.clip((ed + 2 * lam * e + lam**2 * z) / phi, -1, 1))
        np.testing.assert_allclose(control.torque(q, qd, q_ref, qd_ref, qdd_ref), expected, rtol=1e-12, atol=1e-9)
        z = z + control.h * e
        np.testing.assert_allclose(control.state[0], z, rtol=1e-13, atol=1e-15)


def test_sta_torque_is_continuous_in_s() -> None:
    """No switching in the torque: across s = 0 it moves by k1 sqrt(|s|) (the SMC's by 2 Ks at phi -> 0)."""
    spec = make_run("parallel_5r", "circle", "sta")
    ref = spec.reference().sample([1.0])
    tau = []
    for ds in (-1e-10, 1e-10):
        control = ControlLaw.from_spec(spec)
        qd = ref.qd[0] - ds  # s = edot = ds
        tau.append(control.torque(ref.q[0], qd, ref.q[0], ref.qd[0], ref.qdd[0]))
    k1 = np.array(spec.gains["k1"])
    assert np.all(np.abs(tau[1] - tau[0]) <= 2 * k1 * 1e-5 + 1e-6)


@pytest.mark.parametrize(("robot", "contour"), ROBOT_CONTOURS)
def test_presets_derive_from_the_smc(robot: str, contour: str) -> None:
    smc = preset_gains(robot, contour, "smc")
    ks, phi = np.array(smc["ks"]), np.array(smc["phi"])
    sta = preset_gains(robot, contour, "sta")
    np.testing.assert_allclose(np.array(sta["k1"]) * np.sqrt(phi), ks, rtol=1e-12)  # = Ks at |s| = phi
    np.testing.assert_allclose(sta["k2"], 1.1 * (np.array(sta["k1"]) / 1.5) ** 2, rtol=1e-12)  # Levant's pair
    assert sta["lam"] == smc["lam"]
    ismc = preset_gains(robot, contour, "ismc")
    assert (ismc["ks"], ismc["phi"]) == (smc["ks"], smc["phi"])
    assert np.all(np.array(ismc["lam"]) < 0.5 * np.array(smc["lam"]))
    high = make_run(robot, contour, "sta", scenario="high_smc")
    np.testing.assert_allclose(high.gains["k1"], 1.5 * np.array(sta["k1"]), rtol=1e-12)  # scaled as Ks


def test_linear_parts() -> None:
    spec = make_run("serial_3r", "circle", "ismc")
    mass = spec.robot_model().mass_matrix(spec.reference().sample([0.0]).q[0])
    kp, kd = effective_gains(spec, mass)  # type: ignore[misc]
    ks, lam, phi = (np.diag(spec.gains[k]) for k in ("ks", "lam", "phi"))
    np.testing.assert_allclose(kp, 0.9 * mass @ lam @ lam + 2 * ks / np.diag(phi)[:, None] * np.diag(lam)[None, :]
                               * np.eye(3), rtol=1e-12)
    np.testing.assert_allclose(kd, 1.8 * mass @ lam + np.diag(np.diag(ks) / np.diag(phi)), rtol=1e-12)
    assert effective_gains(make_run("serial_3r", "circle", "sta"), mass) is None
    assert law("sta").state_size == law("ismc").state_size == 1


@pytest.mark.parametrize(("robot", "contour"), ROBOT_CONTOURS)
def test_ismc_presets_have_the_smcs_stiffness_and_at_most_its_damping(robot: str, contour: str) -> None:
    """With the exact model, at the reference's start: the ISMC's Kp_eff is the SMC's on every
    joint (Mbar_ii lam^2 + 2 lam Ks/phi = lam_SMC Ks/phi), its Kd_eff at most the SMC's."""
    exact = {"mass": 1.0}
    smc, ismc = make_run(robot, contour, "smc", smc_model=exact), make_run(robot, contour, "ismc", smc_model=exact)
    mass = smc.robot_model().mass_matrix(smc.reference().sample([0.0]).q[0])
    kp_s, kd_s = effective_gains(smc, mass)  # type: ignore[misc]
    kp_i, kd_i = effective_gains(ismc, mass)  # type: ignore[misc]
    np.testing.assert_allclose(np.diagonal(kp_i), np.diagonal(kp_s), rtol=1e-12)
    assert np.all(np.diagonal(kd_i) < np.diagonal(kd_s))
    lam_s, lam_i = np.array(smc.gains["lam"]), np.array(ismc.gains["lam"])
    # below the damping-matching 2 lam = lam_SMC of massless joints, which it nears where Ks / phi
    # outweighs Mbar lam^2 (the thesis arms; not the URDF arms' gentler real-time gains)
    assert np.all(lam_i < lam_s)


@pytest.mark.parametrize(("robot", "contour"), _preset_robot_contours())
def test_ismc_presets_pass_the_real_time_check(robot: str, contour: str) -> None:
    """check-gains' default: zero-order hold + one period of delay, margin x2 (the SMC's lam as it
    failed on the UR5 (circle x1.91) and on every Panda contour)."""
    result = check_gains(make_run(robot, contour, "ismc"), mode="realtime")
    assert result.passes, result.failure()


def test_ismc_removes_the_smcs_steady_error_of_the_gravity_estimate() -> None:
    """Inside its boundary layer the SMC keeps a steady error on the five-bar; the integral removes most of it."""
    smc = simulate(make_run("parallel_5r", "circle", "smc"))
    ismc = simulate(make_run("parallel_5r", "circle", "ismc"))
    assert ismc.metrics.contour_mean < 0.5 * smc.metrics.contour_mean
