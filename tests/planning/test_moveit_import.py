"""MoveIt scene/request pairs (MotionBenchMaker's layout) imported as problems."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from gaide_core.errors import PlanningError
from planning.moveit_import import import_moveit_set, import_moveit_sets
from planning.primitives import Box, Cylinder, Sphere
from planning.problem import load_problems
from planning.robot_model import RobotModel
from tests.conftest import run_cli

UR5 = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
       "wrist_2_joint", "wrist_3_joint")  # fmt: skip
YAW = Rotation.from_euler("z", 0.7).as_quat().tolist()  # x, y, z, w


def _scene() -> dict:
    return {
        "world": {
            "collision_objects": [
                {   # an object pose (MoveIt >= 1.1) with a primitive offset in it
                    "id": "shelf",
                    "pose": {"position": [1.0, 0.0, 0.5], "orientation": YAW},
                    "primitives": [{"type": "box", "dimensions": [0.2, 0.4, 0.02]}],
                    "primitive_poses": [{"position": [0.1, 0.0, 0.0],
                                         "orientation": [0, 0, 0, 1]}],
                },
                {   # orientation as a mapping; a cylinder is [height, radius]
                    "id": "can",
                    "primitives": [{"type": "cylinder", "dimensions": [0.3, 0.05]}],
                    "primitive_poses": [{"position": {"x": 0.5, "y": 0.2, "z": 0.15},
                                         "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}],
                },
                {
                    "id": "ball",
                    "header": {"frame_id": "world"},
                    "primitives": [{"type": "sphere", "dimensions": [0.08]}],
                    "primitive_poses": [{"position": [0.4, -0.3, 0.3]}],
                },
            ]
        }
    }  # fmt: skip


def _request(goals: int = 2) -> dict:
    # the request lists the joints in its own order, gripper joints among them
    names = ["robotiq_85_left_knuckle_joint", *reversed(UR5)]
    start = [0.8, *reversed([0.0, -1.5, 1.5, -1.5, -1.5, 0.0])]
    goal_sets = [
        {"joint_constraints": [{"joint_name": j, "position": 0.1 * (k + 1) * i}
                               for i, j in enumerate(UR5)]}
        for k in range(goals)
    ]  # fmt: skip
    return {"start_state": {"joint_state": {"name": names, "position": start}},
            "goal_constraints": goal_sets}  # fmt: skip


def _write_set(root: Path, n: int = 2, name: str = "cage_ur5") -> Path:
    folder = root / name
    folder.mkdir()
    for i in range(1, n + 1):
        (folder / f"scene{i:04d}.yaml").write_text(yaml.safe_dump(_scene()))
        (folder / f"request{i:04d}.yaml").write_text(yaml.safe_dump(_request()))
    return folder


def test_a_set_becomes_problems_in_the_robots_joint_order(tmp_path: Path) -> None:
    problems = import_moveit_set(_write_set(tmp_path, 3), UR5)
    assert [p.name for p in problems] == ["cage_ur5-0001", "cage_ur5-0002", "cage_ur5-0003"]
    p = problems[0]
    assert p.family == "cage_ur5" and p.seed == 1
    np.testing.assert_array_equal(p.start, [0.0, -1.5, 1.5, -1.5, -1.5, 0.0])
    np.testing.assert_allclose(p.goals, [0.1 * np.arange(6), 0.2 * np.arange(6)])
    box, cyl, ball = p.world.primitives
    assert isinstance(box, Box) and isinstance(cyl, Cylinder) and isinstance(ball, Sphere)
    # the box sits at the object's pose times the primitive's offset
    R = Rotation.from_quat(YAW).as_matrix()
    np.testing.assert_allclose(box.pose[:3, 3], [1.0, 0.0, 0.5] + R @ [0.1, 0.0, 0.0])
    np.testing.assert_allclose(box.pose[:3, :3], R, atol=1e-12)
    np.testing.assert_allclose(box.size, [0.2, 0.4, 0.02])
    assert (cyl.radius, cyl.height) == (0.05, 0.3)
    np.testing.assert_allclose(cyl.pose[:3, 3], [0.5, 0.2, 0.15])
    assert ball.radius == 0.08
    np.testing.assert_allclose(ball.center, [0.4, -0.3, 0.3])
    # a point on the box's top face, along its rotated long axis
    top = box.pose[:3, 3] + R @ [0.0, 0.15, 0.01]
    assert abs(p.world.distance(top[None])[0]) < 1e-12


@pytest.mark.parametrize(
    ("edit", "says"),
    [
        (lambda s, r: s["world"]["collision_objects"][0].update(meshes=[{"vertices": []}]),
         "collision object 'shelf': has meshes; only box, cylinder and sphere"),
        (lambda s, r: s["world"]["collision_objects"][1]["primitives"][0].update(type="cone"),
         "type 'cone' cannot be imported; valid: box"),
        (lambda s, r: s["world"]["collision_objects"][1]["primitives"][0].update(dimensions=[1]),
         "a cylinder's dimensions are [height, radius], got [1]"),
        (lambda s, r: s["world"]["collision_objects"][0]["primitives"][0].update(
            dimensions=[0.2, 0.0, 0.02]), "a box's dimensions must be > 0 m"),
        (lambda s, r: s["world"]["collision_objects"][2]["primitive_poses"][0].update(
            orientation=[0, 0, 0, 2]), "must be a unit quaternion"),
        (lambda s, r: s["world"]["collision_objects"][2].update(
            header={"frame_id": "wrist_3_link"}), "'ball': is given in frame 'wrist_3_link'"),
        (lambda s, r: s.update(robot_state={"attached_collision_objects": [{"object": {}}]}),
         "robot_state has attached collision objects"),
        (lambda s, r: r["goal_constraints"][1].pop("joint_constraints"),
         "goal_constraints[1]: only joint goals can be imported"),
        (lambda s, r: r["goal_constraints"][0]["joint_constraints"].pop(2),
         "no value for joint elbow_joint; the robot plans shoulder_pan_joint"),
        (lambda s, r: r["start_state"]["joint_state"]["position"].pop(),
         "name and position lists of the same length"),
    ],
)  # fmt: skip
def test_what_cannot_be_imported_is_named(tmp_path: Path, edit, says: str) -> None:  # type: ignore[no-untyped-def]
    folder = _write_set(tmp_path, 1)
    scene, request = _scene(), _request()
    edit(scene, request)
    (folder / "scene0001.yaml").write_text(yaml.safe_dump(scene))
    (folder / "request0001.yaml").write_text(yaml.safe_dump(request))
    with pytest.raises(PlanningError, match=re.escape(says)):
        import_moveit_set(folder, UR5)


def test_an_unpaired_or_empty_folder_is_refused(tmp_path: Path) -> None:
    folder = _write_set(tmp_path, 2)
    (folder / "request0002.yaml").unlink()
    with pytest.raises(PlanningError, match="scene0002 has no request file"):
        import_moveit_set(folder, UR5)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(
        PlanningError, match=re.escape("no sceneNNNN.yaml / requestNNNN.yaml files")
    ):
        import_moveit_set(empty, UR5)
    with pytest.raises(PlanningError, match="not a folder"):
        import_moveit_set(tmp_path / "nowhere", UR5)


def test_two_folders_of_one_name_are_refused(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    one, two = _write_set(tmp_path / "a", 1), _write_set(tmp_path / "b", 1)
    assert [p.name for p in import_moveit_sets([one], UR5)] == ["cage_ur5-0001"]
    with pytest.raises(PlanningError, match="have the same name"):
        import_moveit_sets([one, two], UR5)


def test_the_cli_writes_a_problem_file_the_planners_run(tmp_path: Path, robot: RobotModel) -> None:
    assert robot.joint_names == UR5
    out = tmp_path / "mbm.yaml"
    folders = [str(_write_set(tmp_path, 2)), str(_write_set(tmp_path, 1, "box_ur5"))]
    proc = run_cli("scenes", "import-moveit", *folders, "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "3 problems from 2 folder(s)" in proc.stdout
    problems = load_problems(out, robot.dof)
    assert [p.family for p in problems] == ["cage_ur5", "cage_ur5", "box_ur5"]
    assert len(problems[0].world) == 3 and problems[0].goals.shape == (2, 6)
    result = tmp_path / "bench.json"
    proc = run_cli(
        "bench", "planning", "--problem-file", str(out), "--planners", "rrtc", "--budget", "5",
        "--json", str(result),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "rrtc" in proc.stdout and result.exists()
    bad = run_cli(
        "scenes", "import-moveit", str(tmp_path / "nowhere"), "-o", str(tmp_path / "x.yaml")
    )
    assert bad.returncode != 0 and bad.stderr.strip().count("\n") == 0
    assert "not a folder" in bad.stderr and not (tmp_path / "x.yaml").exists()
