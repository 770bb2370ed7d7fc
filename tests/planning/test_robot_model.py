from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from gaide_core.errors import ConfigError, RobotModelError
from planning.ik import solve_ik
from planning.robot_config import load_robot_config
from planning.robot_model import RobotModel, load_robot
from planning.robot_names import DEFAULT_CONFIG, resolve_robot_config, shipped_robots


def test_default_ur5_loads(robot: RobotModel) -> None:
    assert robot.dof == 6
    assert robot.joint_names[0] == "shoulder_pan_joint"
    assert np.allclose(robot.upper, np.pi, atol=1e-6)  # the config's override of +-2 pi
    assert robot.velocity_limits[0] == pytest.approx(3.15)
    assert set(robot.link_meshes) >= {"upper_arm_link", "forearm_link", "wrist_3_link"}


def test_self_collision_pairs_skip_neighbours(robot: RobotModel) -> None:
    pairs = robot.disabled_link_pairs
    assert frozenset(("upper_arm_link", "forearm_link")) in pairs
    assert frozenset(("wrist_2_link", "ee_link")) in pairs  # neighbouring joints
    assert frozenset(("upper_arm_link", "wrist_3_link")) not in pairs


def test_ik_round_trip(robot: RobotModel, rng: np.random.Generator) -> None:
    for _ in range(5):
        q = robot.sample_uniform(rng, 1)[0]
        target = robot.frame_pose(q)
        solutions = solve_ik(robot, target, rng)
        assert solutions, "IK found no solution for a reachable pose"
        for s in solutions:
            reached = robot.frame_pose(s)
            assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 2e-4
            assert np.allclose(reached[:3, :3], target[:3, :3], atol=2e-3)
            assert robot.within_limits(s[None])[0]


def test_ik_unreachable_pose_gives_no_solution(robot: RobotModel, rng: np.random.Generator) -> None:
    far = np.eye(4)
    far[:3, 3] = [3.0, 0.0, 0.5]  # the UR5 reaches about 0.85 m
    assert solve_ik(robot, far, rng) == []


@pytest.mark.parametrize(
    ("q", "message"),
    [
        ([0.0] * 5, "expected (6,)"),
        ([0.0, np.nan, 0, 0, 0, 0], "non-finite values at joints ['shoulder_lift_joint']"),
        ([0.0, 0, 4.0, 0, 0, 0], "elbow_joint = 4.0000 rad is outside its limits"),
    ],
)
def test_bad_configurations_name_the_joint(robot: RobotModel, q: list[float], message: str) -> None:
    with pytest.raises(RobotModelError) as err:
        robot.check_configuration(q)
    assert message in str(err.value)


def test_a_configuration_from_text_is_named_or_angles(robot: RobotModel) -> None:
    home = robot.named_configuration("home")
    np.testing.assert_array_equal(robot.configuration_from_text(" home "), home)
    text = ", ".join(f"{v:.17g}" for v in home)
    np.testing.assert_array_equal(robot.configuration_from_text(text), home)
    for bad in ("hom", "1,2,x", "nan,0,0,0,0,0", ""):
        with pytest.raises(RobotModelError, match=r"6 comma-separated angles .*'home'"):
            robot.configuration_from_text(bad, "--goal")
    with pytest.raises(RobotModelError, match="--goal '1,2' has 2 values; the robot has 6 joints"):
        robot.configuration_from_text("1,2", "--goal")


def test_unknown_frame_lists_valid_names(robot: RobotModel) -> None:
    with pytest.raises(RobotModelError, match=r"valid frames: .*tool0"):
        robot.frame_pose(np.zeros(6), "gripper")
    with pytest.raises(RobotModelError, match="valid links"):
        robot.link("gripper_link")


def _config(tmp_path: Path, urdf: str, extra: str = "") -> Path:
    cfg = tmp_path / "robot.yaml"
    cfg.write_text(f"urdf: {urdf}\nend_effector: tip\n{extra}")
    return cfg


ARM = """<robot name="arm">
  <link name="base"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
  <link name="l1"><collision><geometry>{geometry}</geometry></collision></link>
  <joint name="fix" type="fixed"><parent link="l1"/><child link="tip"/>
    <origin xyz="0.3 0 0"/></joint>
  <link name="tip"/>
</robot>"""


def test_missing_urdf(tmp_path: Path) -> None:
    with pytest.raises(RobotModelError, match="does not exist"):
        load_robot(_config(tmp_path, str(tmp_path / "nope.urdf")))


def test_urdf_that_does_not_parse(tmp_path: Path) -> None:
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'>")
    with pytest.raises(RobotModelError, match="does not parse"):
        load_robot(_config(tmp_path, str(bad)))


def test_missing_mesh_is_named(tmp_path: Path) -> None:
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM.format(geometry='<mesh filename="meshes/gone.stl"/>'))
    robot = load_robot(_config(tmp_path, str(urdf)))
    with pytest.raises(RobotModelError, match=r"gone\.stl"):
        _ = robot.link_meshes


def test_a_shipped_robot_loads_by_name(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    shipped = shipped_robots()
    assert {"ur5", "ur10", "panda", "xarm7"} <= set(shipped)
    assert not any(name.endswith("_spheres") for name in shipped)
    assert resolve_robot_config(None) == DEFAULT_CONFIG == shipped["ur5"]
    monkeypatch.chdir(tmp_path)
    by_name, by_path = load_robot_config("panda"), load_robot_config(shipped["panda"])
    assert by_name.urdf == by_path.urdf and by_name.end_effector == by_path.end_effector
    # a file of that name here is the user's, and wins
    (tmp_path / "panda").write_text("urdf: mine.urdf\n")
    assert resolve_robot_config("panda") == Path("panda")
    with pytest.raises(ConfigError, match="panda, ur10, ur5, xarm7"):
        load_robot_config("pandas")


def test_config_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="does not exist"):
        load_robot_config(tmp_path / "none.yaml")
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM.format(geometry='<box size="0.1 0.1 0.1"/>'))
    with pytest.raises(ConfigError, match="unknown keys \\['margin'\\]"):
        load_robot_config(_config(tmp_path, str(urdf), "margin: 0.1\n"))
    with pytest.raises(ConfigError, match="collision_margin must be >= 0"):
        load_robot_config(_config(tmp_path, str(urdf), "collision_margin: -1\n"))
    robot_cfg = _config(tmp_path, str(urdf), "jerk_limits: [1, 2]\n")
    with pytest.raises(RobotModelError, match="jerk_limits has 2 values; the robot has 1 joints"):
        load_robot(robot_cfg)


#: extra YAML lines of a robot config -> what its refusal says
BAD_CONFIG_LINES = {
    "edge_resolution: 0\n": "edge_resolution must be > 0 m",
    "velocity_limits: [-1]\n": "velocity_limits must be finite and > 0",
    "acceleration_limits: [[1, 2]]\n": "acceleration_limits must be a flat list",
    "jerk_limits: [fast]\n": "jerk_limits must be a list of numbers",
    "ignored_link_pairs: [[a, b, c]]\n": "ignored_link_pairs must be a list of [link_a, link_b]",
    "named_configurations: {rest: null}\n": "named_configurations.rest has no joint values",
    "locked_joints: [j1]\n": "locked_joints must map joint names to values",
    "locked_joints: {j1: open}\n": "locked_joints.j1 must be a number (rad or m), got 'open'",
    "srdf: package://nowhere/arm.srdf\n": "cannot resolve package://nowhere/arm.srdf",
    "base_pose: {xyz: [0, 0], rpy: [0, 0, 0]}\n": "base_pose.xyz must be 3 finite numbers",
    "base_pose: {rpy: [0, .nan, 0]}\n": "base_pose.rpy must be 3 finite numbers",
    "collision_margin: .nan\n": "collision_margin must be a finite number (m)",
    "edge_resolution: .inf\n": "edge_resolution must be a finite number (m)",
    "base_pose: [0, 0, 0]\n": "base_pose must be a mapping",
    "joint_limits: [-1, 1]\n": "joint_limits must be a mapping",
    "collision_margin: five mm\n": "collision_margin must be a number (m), got 'five mm'",
}


@pytest.mark.parametrize("lines", list(BAD_CONFIG_LINES))
def test_robot_config_values_outside_their_limits_are_refused_by_name(
    lines: str, tmp_path: Path
) -> None:
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM.format(geometry='<box size="0.1 0.1 0.1"/>'))
    with pytest.raises(ConfigError, match=re.escape(BAD_CONFIG_LINES[lines])):
        load_robot_config(_config(tmp_path, str(urdf), lines))


def test_a_robot_config_that_is_not_a_mapping_with_a_urdf_is_refused(tmp_path: Path) -> None:
    for text in ("- urdf: arm.urdf\n", "srdf: arm.srdf\n"):
        path = tmp_path / "robot.yaml"
        path.write_text(text)
        with pytest.raises(ConfigError, match="must be a mapping with at least 'urdf'"):
            load_robot_config(path)
