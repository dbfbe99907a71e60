"""The identification's model against Pinocchio as the oracle: the regressor, the payload's frame,
the pseudo-inertia, the base parameters and the options' payload."""

from __future__ import annotations

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from pdsmc_ros.identification.base import base_parameters  # noqa: E402
from pdsmc_ros.identification.consistent import MARGIN, is_consistent  # noqa: E402
from pdsmc_ros.identification.model import (  # noqa: E402
    INERTIAL_FIELDS,
    ArmDynamics,
    arm_of,
    placement_map,
    pseudo_inertia,
)
from pdsmc_ros.robots.urdf_robot import urdf_arm  # noqa: E402


@pytest.fixture(scope="module")
def ur5() -> ArmDynamics:
    return ArmDynamics(arm_of("ur5"))


def test_the_rigid_part_is_pinocchios_inverse_dynamics_and_the_joint_terms_are_added(ur5: ArmDynamics) -> None:
    rng = np.random.default_rng(0)
    q, qd, qdd = rng.normal(size=(3, 8, 6))
    params = ur5.nominal.copy()
    layout = ur5.layout
    params[layout.joint_field("armature")] = [0.3, 0.2, 0.1, 0.05, 0.04, 0.03]
    params[layout.joint_field("friction_coulomb")] = [5.0, 4.0, 3.0, 1.0, 0.5, 0.2]
    params[layout.joint_field("friction_viscous")] = [2.0, 1.5, 1.0, 0.4, 0.3, 0.1]
    tau = ur5.torque(params, q, qd, qdd)
    data = ur5.model.createData()
    rigid = np.array([pin.rnea(ur5.model, data, q[s], qd[s], qdd[s]) for s in range(8)])
    joint = (params[layout.joint_field("armature")] * qdd + params[layout.joint_field("friction_coulomb")] * np.sign(qd)
             + params[layout.joint_field("friction_viscous")] * qd)
    np.testing.assert_allclose(tau, rigid + joint, atol=1e-10)
    np.testing.assert_allclose(ur5.consistent_torque(params, q, qd, qdd), tau, atol=1e-10)


def test_the_payload_columns_are_a_body_at_the_tool_frame(ur5: ArmDynamics) -> None:
    """A 2 kg body at the tool frame: the payload's ten parameters give the torque of a Pinocchio model
    with that body added at the frame."""
    rng = np.random.default_rng(1)
    q, qd, qdd = rng.normal(size=(3, 5, 6))
    body = pin.Inertia(2.0, np.array([0.01, -0.02, 0.05]), np.diag([2e-3, 3e-3, 1e-3]))
    params = ur5.nominal.copy()
    params[ur5.layout.payload] = body.toDynamicParameters()
    model = ur5.model.copy()
    frame = model.frames[model.getFrameId("tool0")]
    model.inertias[frame.parentJoint] = model.inertias[frame.parentJoint] + frame.placement.act(body)
    data = model.createData()
    expected = np.array([pin.rnea(model, data, q[s], qd[s], qdd[s]) for s in range(5)])
    np.testing.assert_allclose(ur5.torque(params, q, qd, qdd), expected, atol=1e-10)


def test_the_placement_map_is_se3_act() -> None:
    for seed in range(5):
        np.random.seed(seed)
        placement, inertia = pin.SE3.Random(), pin.Inertia.Random()
        mapped = placement_map(placement.rotation, placement.translation) @ inertia.toDynamicParameters()
        np.testing.assert_allclose(mapped, placement.act(inertia).toDynamicParameters(), atol=1e-12)


def test_the_pseudo_inertia_is_positive_definite_exactly_for_bodies() -> None:
    box = pin.Inertia.FromBox(2.0, 0.3, 0.2, 0.1)
    assert np.linalg.eigvalsh(pseudo_inertia(box.toDynamicParameters()))[0] > 0.0
    # the triangle inequality broken (Izz > Ixx + Iyy): a tensor positive definite, no body has it
    flat = pin.Inertia(1.0, np.zeros(3), np.diag([0.01, 0.01, 0.05]))
    assert np.all(np.linalg.eigvalsh(flat.inertia) > 0.0)
    assert np.linalg.eigvalsh(pseudo_inertia(flat.toDynamicParameters()))[0] < 0.0
    negative = box.toDynamicParameters()
    negative[0] = -1.0
    assert np.linalg.eigvalsh(pseudo_inertia(negative))[0] < 0.0


def test_base_parameters_give_the_same_torques(ur5: ArmDynamics) -> None:
    base = base_parameters(ur5)
    rng = np.random.default_rng(2)
    q, qd, qdd = rng.normal(size=(3, 30, 6))
    y = ur5.regressor(q, qd, qdd)
    for _ in range(3):
        params = ur5.nominal + rng.normal(size=ur5.nominal.size)
        np.testing.assert_allclose(y @ params, base.columns(y) @ base.of(params), atol=1e-8 * np.abs(y @ params).max())
    assert np.linalg.matrix_rank(base.columns(y)) == base.size
    # the payload is never a base parameter of its own: it sits on the tool's link
    payload = set(range(ur5.layout.payload.start, ur5.layout.payload.stop))
    assert not payload & set(base.independent.tolist())
    # the structure, not the sample: another seed, the same base parameters
    other = base_parameters(ur5, seed=7)
    np.testing.assert_array_equal(base.independent, other.independent)
    np.testing.assert_allclose(base.grouping, other.grouping, atol=1e-8)


def test_a_planar_arm_has_parameters_no_torque_sees() -> None:
    twin = ArmDynamics(arm_of("serial_3r"))
    base = base_parameters(twin)
    names = twin.layout.names
    assert {names[k] for k in base.unidentifiable} >= {"link1.Ixy", "link1.Iyz", "link2.Ixy"}
    assert base.size < twin.layout.size - len(base.unidentifiable)


def test_the_options_payload_is_in_the_arms_model_and_the_prior(tmp_path) -> None:  # noqa: ANN001
    source = arm_of("ur5")
    loaded = urdf_arm(source.urdf, ee_frame="tool0", payload_mass=1.5, payload_com=[0.0, 0.01, 0.04],
                      friction_viscous=0.5, friction_coulomb=[1, 2, 3, 4, 5, 6])
    dynamics = ArmDynamics(loaded)
    layout = dynamics.layout
    assert dynamics.nominal[layout.payload][0] == pytest.approx(1.5)
    np.testing.assert_allclose(dynamics.nominal[layout.payload][1:4] / 1.5, [0.0, 0.01, 0.04])
    np.testing.assert_allclose(dynamics.nominal[layout.links], ArmDynamics(source).nominal[layout.links], atol=1e-12)
    np.testing.assert_allclose(dynamics.nominal[layout.joint_field("friction_viscous")], 0.5)
    np.testing.assert_allclose(dynamics.nominal[layout.joint_field("friction_coulomb")], [1, 2, 3, 4, 5, 6])
    # the robot built from it carries the load: its gravity torque is the payload's
    q = np.array([0.1, -1.2, 1.0, -1.4, -1.5, 0.3])
    with_load = pin.computeGeneralizedGravity(loaded.model, loaded.model.createData(), q)
    without = pin.computeGeneralizedGravity(source.model, source.model.createData(), q)
    np.testing.assert_allclose(with_load - without, dynamics.torque(dynamics.nominal, q[None], np.zeros((1, 6)),
                                                                     np.zeros((1, 6)))[0]
                               - dynamics.torque(ArmDynamics(source).nominal, q[None], np.zeros((1, 6)),
                                                 np.zeros((1, 6)))[0], atol=1e-10)


def test_the_urdfs_own_parameters_are_checked_for_consistency() -> None:
    ur5 = ArmDynamics(arm_of("ur5"))
    assert np.all(is_consistent(ur5.nominal, ur5))
    # a body's URDF inertial is the prior as it is
    np.testing.assert_array_equal(ur5.nominal[ur5.layout.link(0)], ur5.model.inertias[1].toDynamicParameters())
    twin = ArmDynamics(arm_of("serial_3r"))
    # the thesis URDF's planar links carry a 1e-6 placeholder out-of-plane inertia: no body has it ...
    raw = np.concatenate([twin.model.inertias[i + 1].toDynamicParameters() for i in range(twin.n)])
    as_given = twin.nominal.copy()
    as_given[: 10 * twin.n] = raw
    assert twin.layout.link(twin.n - 1).stop == 10 * twin.n
    assert not np.any(is_consistent(as_given, twin)[: twin.n])
    # ... so the prior is a thin rod's (the stand-in's rule), strictly a body, its in-plane moment kept
    assert np.all(is_consistent(twin.nominal, twin, margin=MARGIN)[: twin.n])
    iyy = INERTIAL_FIELDS.index("Iyy")
    np.testing.assert_allclose(twin.nominal[iyy: 10 * twin.n: 10], raw[iyy::10])
    changed = twin.nominal[: 10 * twin.n] != raw
    assert set(np.flatnonzero(changed) % 10) == {INERTIAL_FIELDS.index("Izz")}
