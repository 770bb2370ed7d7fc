"""A robot whose base is not at the world origin: forward kinematics, IK, the collision
spheres and the simulator all place it at the config's ``base_pose``."""

from __future__ import annotations

import dataclasses

import numpy as np
import pybullet as pb
import pytest

from execution.sim_world import SimWorld
from gaide_core.transforms import from_xyz_rpy, invert, transform_error
from planning.checker import make_checker
from planning.ik import IKCfg, solve_ik
from planning.robot_config import load_robot_config
from planning.robot_model import RobotModel
from planning.robot_setup import robot_and_spheres

T_WORLD_BASE = from_xyz_rpy([0.4, -0.3, 0.75], [0.2, -0.1, 1.3])


@pytest.fixture(scope="module")
def robots() -> tuple[RobotModel, RobotModel]:
    plain, _ = robot_and_spheres(None)
    posed = RobotModel(dataclasses.replace(load_robot_config(None), T_world_base=T_WORLD_BASE))
    return plain, posed


def test_forward_kinematics_carries_the_base_pose(robots: tuple[RobotModel, RobotModel]) -> None:
    plain, posed = robots
    for q in plain.sample_uniform(np.random.default_rng(0), 20):
        np.testing.assert_allclose(
            posed.frame_pose(q), T_WORLD_BASE @ plain.frame_pose(q), atol=1e-12
        )


def test_ik_reaches_a_world_target_of_the_posed_robot(
    robots: tuple[RobotModel, RobotModel],
) -> None:
    _, posed = robots
    rng = np.random.default_rng(3)
    q_true = posed.sample_uniform(rng, 1)[0]
    target = posed.frame_pose(q_true)
    solutions = solve_ik(posed, target, rng, cfg=IKCfg(restarts=48))
    assert solutions
    for q in solutions:
        dt, dr = transform_error(posed.frame_pose(q), target)
        assert dt < 1e-3 and dr < 1e-2
    # the same world target is a different (base-frame) target for the robot at the origin
    dt, _ = transform_error(invert(T_WORLD_BASE) @ target, target)
    assert dt > 0.1


def test_collision_spheres_move_with_the_base(robots: tuple[RobotModel, RobotModel]) -> None:
    plain, posed = robots
    _, spheres = robot_and_spheres(None)
    q = plain.named_configuration("home")[None]
    centres_plain = make_checker(plain, spheres).sphere_centers(q)[0]
    centres_posed = make_checker(posed, spheres).sphere_centers(q)[0]
    expected = centres_plain @ T_WORLD_BASE[:3, :3].T + T_WORLD_BASE[:3, 3]
    np.testing.assert_allclose(centres_posed, expected, atol=1e-12)


def test_the_simulator_places_the_robot_at_its_base_pose(
    robots: tuple[RobotModel, RobotModel],
) -> None:
    _, posed = robots
    q = posed.sample_uniform(np.random.default_rng(4), 1)[0]
    with SimWorld(posed) as world:
        world.reset(q)
        link = next(i for i, name in world.link_names.items() if name == "tool0")
        state = pb.getLinkState(
            world.body, link, computeForwardKinematics=True, physicsClientId=world.client
        )
    np.testing.assert_allclose(state[4], posed.frame_pose(q)[:3, 3], atol=1e-6)
