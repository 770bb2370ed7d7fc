from __future__ import annotations

import numpy as np
import pytest

from execution.sim_cfg import SimCfg
from execution.simulate import SimStatus, simulate
from execution.trajectory import TimedTrajectory
from gaide_core.errors import ExecutionError
from planning.collision import CollisionChecker
from planning.primitives import Box, PrimitiveWorld
from planning.robot_model import RobotModel


def test_the_simulation_tracks_a_trajectory_in_free_space(
    small_traj: TimedTrajectory, robot: RobotModel
) -> None:
    res = simulate(small_traj, robot, cfg=SimCfg(settle_s=0.2))
    assert res.status is SimStatus.CLEAR and not res.contacts
    assert res.rms_all_rad < 1e-3 and res.max_rad.max() < 5e-3
    assert len(res.log.t) == len(small_traj.t) + 20  # 0.2 s of holding at 100 Hz
    np.testing.assert_allclose(res.log.q[-1], small_traj.q[-1], atol=1e-3)
    assert res.log.names == robot.joint_names


def test_a_planted_obstacle_is_reported_as_a_contact(
    small_traj: TimedTrajectory, robot: RobotModel, free_checker: CollisionChecker
) -> None:
    # A box around where the hand is halfway through the trajectory.
    k = len(small_traj.t) // 2
    hand = free_checker.sphere_centers(small_traj.q[k][None])[0][-1]
    pose = np.eye(4)
    pose[:3, 3] = hand
    world = PrimitiveWorld([Box(np.array([0.15, 0.15, 0.15]), pose)])
    res = simulate(small_traj, robot, primitives=world)
    assert res.status is SimStatus.CONTACT
    first = res.contacts[0]
    assert first.obstacle == "box 0"
    assert first.link in {"wrist_2_link", "wrist_3_link", "ee_link", "wrist_1_link", "tool0"}
    assert first.first_s <= small_traj.t[k] + 1e-9
    assert first.mesh_confirmed is True  # the URDF's meshes hit the box too
    assert res.max_rad.max() > 1e-3  # the box pushes the arm off its plan


def test_a_cloud_scene_becomes_voxel_boxes(
    small_traj: TimedTrajectory, robot: RobotModel, free_checker: CollisionChecker
) -> None:
    k = len(small_traj.t) // 2
    hand = free_checker.sphere_centers(small_traj.q[k][None])[0][-1]
    rng = np.random.default_rng(0)
    cloud = hand + rng.uniform(-0.05, 0.05, size=(300, 3))
    res = simulate(small_traj, robot, cloud=cloud)
    assert res.status is SimStatus.CONTACT
    assert res.contacts[0].obstacle.startswith("voxel at")


def test_another_robots_trajectory_is_refused(
    small_traj: TimedTrajectory, robot: RobotModel
) -> None:
    other = TimedTrajectory(
        t=small_traj.t,
        q=small_traj.q,
        qd=small_traj.qd,
        qdd=small_traj.qdd,
        joint_names=tuple(reversed(small_traj.joint_names)),
        rate_hz=small_traj.rate_hz,
    )
    with pytest.raises(ExecutionError, match="not the robot's"):
        simulate(other, robot)
