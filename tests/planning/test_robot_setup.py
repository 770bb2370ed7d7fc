"""Bring your own robot: ``gaide robot setup`` on example-robot-data's URDFs, locked joints,
families placed by reach, and the shipped Panda, UR10 and xArm7 configs planning and timing
a path on every family."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from execution.ruckig_timing import RuckigParameterizer
from execution.timing_cfg import TimingCfg
from execution.verify import limit_violations, swept_collisions
from gaide_core.errors import RobotModelError
from planning.checker import make_checker
from planning.families import generate_problem, reach, workspace_scale
from planning.family_names import FAMILIES, split_seed
from planning.planner import PlanStatus
from planning.robot_config import example_robot_data_share, load_robot_config
from planning.robot_model import RobotModel
from planning.robot_setup import robot_and_spheres
from planning.rrtc import CompiledRRTConnect, RRTCCfg
from planning.setup_assistant import (
    SetupCfg,
    SetupResult,
    default_tip,
    read_urdf_tree,
    setup_robot,
    tool_frame,
)
from tests.conftest import ROOT

DATA = ROOT / "planning" / "data"
SHARE = example_robot_data_share()
ROBOTS = SHARE / "example-robot-data" / "robots" if SHARE else Path("/nonexistent")
PANDA_URDF = ROBOTS / "panda_description" / "urdf" / "panda.urdf"


@pytest.fixture(scope="module")
def panda_setup(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, SetupResult]:
    out = tmp_path_factory.mktemp("setup") / "panda.yaml"
    return out, setup_robot(PANDA_URDF, out, SetupCfg(samples=2000))


def test_setup_makes_a_panda_config_from_its_urdf_alone(
    panda_setup: tuple[Path, SetupResult],
) -> None:
    out, result = panda_setup
    robot, spheres = robot_and_spheres(str(out))
    assert robot.dof == 7 and robot.joint_names[-1] == "panda_joint7"
    # The fingers hang off the hand: off the chain, held at the value nearest 0.
    assert robot.config.locked_joints == {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
    assert robot.config.end_effector == "panda_hand_tcp"
    assert robot.config.world_ignored_links == ("panda_link0",)
    assert out.with_name("panda_spheres.yaml").is_file()
    assert {"panda_leftfinger", "panda_hand", "panda_link7"} <= set(spheres.link_names)
    np.testing.assert_allclose(robot.velocity_limits, [2.175] * 4 + [2.61] * 3)
    assert np.all(robot.acceleration_limits == 5.0) and np.all(robot.jerk_limits == 50.0)
    # The matrix finds what MoveIt's setup assistant wrote in the Panda's own SRDF.
    disabled = result.disabled
    assert disabled[("panda_hand", "panda_link3")] == "never"
    assert disabled[("panda_hand", "panda_link4")] == "never"
    assert set(robot.config.ignored_link_pairs) == set(disabled)
    home = robot.named_configuration("home")
    checker = make_checker(robot, spheres)
    assert checker.config_valid_one(home)


def test_the_urdf_tree_picks_the_arm_chain_and_its_tool_frame() -> None:
    tree = read_urdf_tree(PANDA_URDF)
    assert tree.root == "panda_link0"
    assert default_tip(tree, tree.root) == "panda_hand"
    assert tool_frame(tree, "panda_hand") == "panda_hand_tcp"
    ur10 = read_urdf_tree(ROBOTS / "ur_description" / "urdf" / "ur10_robot.urdf")
    tip = default_tip(ur10, ur10.root)
    assert (tip, tool_frame(ur10, tip)) == ("wrist_3_link", "tool0")


def test_locked_joints_use_the_reduced_model(tmp_path: Path) -> None:
    config = load_robot_config(DATA / "panda.yaml")
    robot = RobotModel(config)
    poses = robot.link_poses(robot.named_configuration("home"))
    gap = np.linalg.norm(poses["panda_leftfinger"][:3, 3] - poses["panda_rightfinger"][:3, 3])
    assert gap == pytest.approx(0.08, abs=1e-9)  # each finger 4 cm out
    with pytest.raises(RobotModelError, match="outside its limits"):
        RobotModel(config.replace(locked_joints={"panda_finger_joint1": 0.2}))
    with pytest.raises(RobotModelError, match="has no joint 'thumb'"):
        RobotModel(config.replace(locked_joints={"thumb": 0.0}))


def test_families_are_placed_by_the_robots_reach(robot: RobotModel) -> None:
    assert workspace_scale(robot) == 1.0  # the paper's families, unchanged for the UR5
    ur10, _ = robot_and_spheres(str(DATA / "ur10.yaml"))
    assert reach(ur10) / reach(robot) == pytest.approx(1.41, abs=0.01)
    assert workspace_scale(ur10) == pytest.approx(1.41)
    problem = generate_problem("tabletop", split_seed("test", 0), ur10, _)
    table = problem.world.primitives[0]
    assert table.size[0] == pytest.approx(1.6 * 1.41)


@pytest.mark.parametrize("name", ["panda", "ur10", "xarm7"])
@pytest.mark.parametrize("family", FAMILIES)
def test_shipped_robots_plan_and_time_every_family(name: str, family: str) -> None:
    robot, spheres = robot_and_spheres(str(DATA / f"{name}.yaml"))
    problem = generate_problem(family, split_seed("test", 1), robot, spheres, category="free2tight")
    checker = make_checker(robot, spheres, problem.world)
    planner = CompiledRRTConnect(RRTCCfg(max_iterations=200_000))
    result = planner.search(checker, problem.start, problem.goal, np.random.default_rng(0))
    assert result.status is PlanStatus.SUCCESS, result.detail
    assert checker.first_invalid_edge(result.path) is None
    traj = RuckigParameterizer(TimingCfg(rate_hz=100.0)).parameterize(result.path, checker)
    assert limit_violations(traj) == 0
    assert swept_collisions(traj, checker, rate_hz=250.0) == 0
    np.testing.assert_allclose(traj.q[-1], problem.goal, atol=1e-6)
