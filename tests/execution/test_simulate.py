from __future__ import annotations

import numpy as np
import pytest

from execution.sim_cfg import SimCfg
from execution.simulate import SimStatus, simulate
from execution.trajectory import TimedTrajectory
from gaide_core.errors import ExecutionError
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.primitives import Box, PrimitiveWorld
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel


def test_the_simulation_tracks_a_trajectory_in_free_space(
    small_traj: TimedTrajectory, robot: RobotModel
) -> None:
    res = simulate(small_traj, robot, cfg=SimCfg(settle_s=0.2))
    assert res.status is SimStatus.CLEAR and not res.contacts
    assert res.controller == "servo" and res.rate_hz == 500.0  # the servo model by default
    # The servo's 6 ms delay is most of the error against the plan at the same time.
    assert res.rms_all_rad < 0.01 and res.max_all_rad < 0.02
    assert res.max_after_delay_rad is not None and res.max_after_delay_rad.max() < 1e-3
    # Every 2 ms cycle of the 100 Hz plan, the 3-cycle delay, then 0.2 s of holding.
    assert len(res.log.t) == round(small_traj.duration * 500) + 1 + 3 + 100
    np.testing.assert_allclose(res.log.q[-1], small_traj.q[-1], atol=1e-3)
    assert res.log.names == robot.joint_names


def test_the_ideal_controller_stays_selectable(
    small_traj: TimedTrajectory, robot: RobotModel
) -> None:
    res = simulate(small_traj, robot, cfg=SimCfg(settle_s=0.2, controller="ideal"))
    assert res.status is SimStatus.CLEAR and res.controller == "ideal"
    assert res.rms_all_rad < 1e-3 and res.max_rad.max() < 5e-3
    assert res.delay_s == 0.0 and res.rate_hz == small_traj.rate_hz
    assert len(res.log.t) == len(small_traj.t) + 20  # 0.2 s of holding at 100 Hz
    np.testing.assert_allclose(res.log.q[-1], small_traj.q[-1], atol=1e-3)


def test_a_planted_obstacle_is_reported_as_a_contact(
    small_traj: TimedTrajectory,
    robot: RobotModel,
    spheres: SphereModel,
    free_checker: CollisionChecker,
) -> None:
    # A box around where the hand is halfway through the trajectory.
    k = len(small_traj.t) // 2
    hand = free_checker.sphere_centers(small_traj.q[k][None])[0][-1]
    pose = np.eye(4)
    pose[:3, 3] = hand
    world = PrimitiveWorld([Box(np.array([0.15, 0.15, 0.15]), pose)])
    checker = make_checker(robot, spheres, world)
    res = simulate(small_traj, robot, primitives=world, checker=checker)
    assert res.status is SimStatus.CONTACT
    first = res.contacts[0]
    assert first.obstacle == "box 0"
    assert first.link in {"wrist_2_link", "wrist_3_link", "ee_link", "wrist_1_link", "tool0"}
    assert first.first_s <= small_traj.t[k] + res.delay_s + 1e-9
    assert first.mesh_confirmed is True  # the URDF's meshes hit the box too
    # The box pushes the arm off its plan, beyond the servo's delay.
    assert res.max_after_delay_rad is not None and res.max_after_delay_rad.max() > 1e-3
    # The executed motion loses the margin: the check of the achieved configurations says so.
    assert res.executed_min_clearance_m is not None
    assert res.executed_min_clearance_m < checker.margin and res.clearance_ok is False
    assert res.executed_invalid is not None and res.executed_invalid > 0
    assert res.summary()["executed_clearance_ok"] is False


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


def test_on_a_cloud_the_reports_take_the_true_distance_where_the_lookup_refuses(
    robot: RobotModel, spheres: SphereModel, free_checker: CollisionChecker
) -> None:
    """A one-point cloud 2 mm beyond the margin of the outermost sphere, on a coarse lattice:
    the checker's look-up (a lower bound) refuses the configuration, the true distance keeps
    the margin, and the report goes by the truth; 2 mm inside the margin, it is invalid."""
    from execution.simulate import report_validity
    from planning.distance_field import CloudWorld

    q = np.array([0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0])[None]
    centres = free_checker.sphere_centers(q)[0]
    far = CloudWorld(centres.mean(axis=0)[None] + 1.0, voxel=0.04, band=0.3)
    checked = np.isfinite(make_checker(robot, spheres, far).sphere_clearance(q)[0])
    away = np.linalg.norm(centres - centres.mean(axis=0), axis=1)
    s = int(np.argmax(np.where(checked, away, -np.inf)))
    out = (centres[s] - centres.mean(axis=0)) / away[s]
    for beyond, valid in ((0.002, True), (-0.002, False)):
        point = centres[s] + out * (free_checker.world_radii[s] + free_checker.margin + beyond)
        checker = make_checker(robot, spheres, CloudWorld(point[None], voxel=0.04, band=0.3))
        truth = np.min(
            np.linalg.norm(centres[checked] - point, axis=1) - checker.world_radii[checked]
        )
        assert truth == pytest.approx(checker.margin + beyond)  # the outermost sphere is nearest
        assert not checker.config_valid(q)[0]  # the look-up refuses both
        ok, clearance = report_validity(checker, q)
        assert ok[0] == valid and clearance[0] == pytest.approx(truth)
