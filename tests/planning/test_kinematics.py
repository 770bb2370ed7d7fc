from __future__ import annotations

import numpy as np

from planning.collision import SphereCollisionChecker
from planning.kinematics import BatchKinematics, reference_points
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel


def test_batched_sphere_fk_matches_pinocchio(
    robot: RobotModel, spheres: SphereModel, rng: np.random.Generator
) -> None:
    checker = SphereCollisionChecker(robot, spheres)
    Q = robot.sample_uniform(rng, 300)
    batched = checker.sphere_centers(Q)
    for q, ours in zip(Q, batched, strict=True):
        ref = reference_points(robot, q, checker.sphere_joint, checker.sphere_local)
        np.testing.assert_allclose(ours, ref, atol=1e-12)


def test_batched_joint_poses_match_pinocchio(robot: RobotModel, rng: np.random.Generator) -> None:
    import pinocchio as pin

    kin = BatchKinematics(robot)
    Q = robot.sample_uniform(rng, 50)
    R, t = kin.joint_poses(Q)
    for b, q in enumerate(Q):
        pin.forwardKinematics(robot.model, robot.data, q)
        for j in range(1, robot.model.njoints):
            np.testing.assert_allclose(R[j][b], robot.data.oMi[j].rotation, atol=1e-12)
            np.testing.assert_allclose(t[j][b], robot.data.oMi[j].translation, atol=1e-12)
