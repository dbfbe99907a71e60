"""Link frames of a URDF (issue 17's /tf and live view) against Pinocchio's forward kinematics."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pinocchio")

import pinocchio as pin  # noqa: E402

from pdsmc_ros.robots import make_robot, robot_params  # noqa: E402
from pdsmc_ros.robots.catalog import resolve_robot  # noqa: E402
from pdsmc_ros.robots.frames import LinkFrames, compose  # noqa: E402
from pdsmc_ros.robots.urdf import robot_urdf  # noqa: E402


@pytest.mark.parametrize("arm", ["ur5", "panda", "parallel_5r"])
def test_link_frames_are_pinocchio_forward_kinematics(arm: str) -> None:
    urdf = robot_urdf(arm, robot_params(arm)) if arm == "parallel_5r" else make_robot(resolve_robot(arm)).urdf
    frames = LinkFrames(urdf)
    model = pin.buildModelFromXML(urdf)
    data = model.createData()
    rng = np.random.default_rng(17)
    for _ in range(5):
        q = rng.uniform(-1.0, 1.0, model.nq)
        pin.framesForwardKinematics(model, data, q)
        names = [model.names[i] for i in range(1, model.njoints)]
        placed = compose(frames.static() + frames.moving_transforms(dict(zip(names, q, strict=True))), frames.root)
        for frame in model.frames:
            if frame.type == pin.FrameType.BODY and frame.name in placed:
                np.testing.assert_allclose(placed[frame.name], data.oMf[model.getFrameId(frame.name)].homogeneous,
                                           rtol=0, atol=1e-12, err_msg=frame.name)
    assert set(frames.moving) == set(names)
    for t in frames.static() + frames.moving_transforms({}):
        assert abs(np.linalg.norm(t.rotation) - 1.0) < 1e-12 and t.rotation[3] >= 0.0
