"""Problem files: strict validation with errors that name the file, the problem and the
field; rpy poses; several goals (loading, round trip, path check, harness); safe loading
(binary files, alias bombs, deep nesting, size limit); the CLI's one-line error."""

from __future__ import annotations

import json
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from gaide_core.errors import PlanningError
from gaide_core.transforms import from_xyz_rpy
from planning import harness
from planning import problem as problem_module
from planning.path_check import check_path
from planning.planner import PlanResult, PlanStatus
from planning.primitives import Box, PrimitiveWorld, Sphere
from planning.problem import Problem, load_problems, problem_from_dict, save_problems
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel
from tests.conftest import run_cli

Q0 = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]  # rad, valid for the UR5 in an empty world
G1 = [-0.5, -1.57, 1.57, -1.57, -1.57, 0.0]
G2 = [0.4, -1.37, 1.57, -1.57, -1.57, 0.0]
OUT_OF_LIMITS = [3.5, -1.57, 1.57, -1.57, -1.57, 0.0]  # joint 0 beyond +pi
FAR_SPHERE = "{type: sphere, radius: 0.05, center: [2, 2, 2]}"
GOOD = f"  - {{name: a, start: {Q0}, goal: {G1}, obstacles: [{FAR_SPHERE}]}}\n"


def _write(tmp_path: Path, text: str | bytes, name: str = "bad.yaml") -> Path:
    path = tmp_path / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def _second(problem: str) -> str:
    """A file whose problem 1 is ``problem`` (a YAML flow mapping), after a good one."""
    return "problems:\n" + GOOD + f"  - {problem}\n"


def _box(pose: str, size: str = "[0.1, 0.2, 0.3]") -> str:
    return _second(f"{{name: b, start: {Q0}, goal: {G1}, obstacles: [{{type: box, size: {size}, pose: {pose}}}]}}")  # fmt: skip


def _obstacle(obstacle: str) -> str:
    return _second(f"{{name: b, start: {Q0}, goal: {G1}, obstacles: [{FAR_SPHERE}, {obstacle}]}}")  # fmt: skip


def _with(**fields: str) -> str:
    """Problem 1 'b' with some of its fields written as given (YAML flow text)."""
    item = {"name": "b", "start": str(Q0), "goal": str(G1), "obstacles": "[]"} | fields
    return _second("{" + ", ".join(f"{k}: {v}" for k, v in item.items()) + "}")


# (id, file name, content, fragments the one-line message must hold besides the file's path)
BAD_FILES: list[tuple[str, str, str, list[str]]] = [
    ("seed-not-integer", "bad.yaml", _with(seed="1.5"),
     ["problem 1 'b'", "seed: must be an integer >= 0, got 1.5"]),
    ("seed-bool", "bad.yaml", _with(seed="true"), ["problem 1 'b'", "seed: must be an integer"]),
    ("seed-negative", "bad.yaml", _with(seed="-3"), ["problem 1 'b'", "seed: must be an integer >= 0, got -3"]),
    ("start-not-numeric", "bad.yaml", _with(start="[0, a, 0, 0, 0, 0]"),
     ["problem 1 'b'", "start[1]: must be a number, got 'a'"]),
    ("start-nan", "bad.yaml", _with(start="[.nan, 0, 0, 0, 0, 0]"),
     ["problem 1 'b'", "start[0]: must be a finite number, got nan"]),
    ("start-overflow", "bad.yaml", _with(start="[1.0e+999, 0, 0, 0, 0, 0]"),
     ["problem 1 'b'", "start[0]: must be a finite number, got inf"]),
    ("start-huge-int", "bad.yaml", _with(start=f"[{10**400}, 0, 0, 0, 0, 0]"),
     ["problem 1 'b'", "start[0]: must be a finite number"]),
    ("start-short", "bad.yaml", _with(start="[0, 0, 0]"),
     ["problem 1 'b'", "start: must be 6 finite joint values (rad), got [0, 0, 0] (3 values)"]),
    ("start-not-a-list", "bad.yaml", _with(start="home"),
     ["problem 1 'b'", "start: must be 6 finite joint values (rad), got 'home'"]),
    ("goal-ragged", "bad.yaml", _with(goal=f"[{G1}, [0, 0, 0, 0, 0]]"),
     ["problem 1 'b'", "goal[1]: must be 6 finite joint values (rad)", "(5 values)"]),
    ("goal-inf", "bad.yaml", _with(goal="[0, 0, 0, .inf, 0, 0]"),
     ["problem 1 'b'", "goal[3]: must be a finite number, got inf"]),
    ("goal-empty", "bad.yaml", _with(goal="[]"),
     ["problem 1 'b'", "goal: must be 6 finite joint values (rad), or a list of such vectors"]),
    ("goal-mixed", "bad.yaml", _with(goal=f"[{G1[0]}, {G1}]"),
     ["problem 1 'b'", "goal: must be 6 finite joint values (rad), or a list of such vectors", "(2 values)"]),
    ("goals-key", "bad.yaml", _with(goals=f"[{G1}]"),
     ["problem 1 'b'", "unknown key 'goals'; valid: name, family, seed, difficulty, start, goal, obstacles", "goal: [[...], [...]]"]),
    ("problem-unknown-key", "bad.yaml", _with(frame="base"),
     ["problem 1 'b'", "unknown key 'frame'; valid: name, family"]),
    ("problem-missing-goal", "bad.yaml", _second(f"{{name: b, start: {Q0}, obstacles: []}}"),
     ["problem 1 'b'", "missing 'goal'"]),
    ("name-not-text", "bad.yaml", _with(name="7"),
     ["problem 1:", "name: must be non-empty text, got 7"]),
    ("difficulty", "bad.yaml", _with(difficulty="hard"),
     ["problem 1 'b'", "difficulty: 'hard' is not one of ['free2free'"]),
    ("obstacles-null", "bad.yaml", _with(obstacles="null"),
     ["problem 1 'b'", "obstacles: must be a list of obstacles ([] for none), got null"]),
    ("top-level-key", "bad.yaml", "version: 2\n" + _with(),
     ["unknown top-level key 'version'; valid: problems"]),
    ("duplicate-names", "bad.yaml", _with(name="a"),
     ["duplicate problem names ['a'] ('a' is problems [0, 1])"]),
    ("obstacle-flat-keys", "bad.yaml",
     _obstacle("{type: box, size: [0.1, 0.1, 0.1], position: [0.5, 0, 0.2], orientation_quat_xyzw: [0, 0, 0, 1]}"),
     ["problem 1 'b'", "obstacles[1]: unknown keys 'position', 'orientation_quat_xyzw'; valid for a box: type, size, pose", "pose: {xyz"]),
    ("obstacle-type", "bad.yaml", _obstacle("{type: cone, radius: 0.1}"),
     ["problem 1 'b'", "obstacles[1].type: unknown type 'cone'; valid: box, cylinder, sphere"]),
    ("obstacle-no-type", "bad.yaml", _obstacle("{radius: 0.1, center: [0, 0, 0]}"),
     ["problem 1 'b'", "obstacles[1]: missing 'type'; valid: box, cylinder, sphere"]),
    ("cylinder-missing-height", "bad.yaml", _obstacle("{type: cylinder, radius: 0.1, pose: {xyz: [0, 0, 0], rpy: [0, 0, 0]}}"),
     ["problem 1 'b'", "obstacles[1]: missing 'height'; a cylinder needs type, radius, height, pose"]),
    ("box-missing-pose", "bad.yaml", _obstacle("{type: box, size: [0.1, 0.1, 0.1]}"),
     ["problem 1 'b'", "obstacles[1]: missing 'pose'; a box needs type, size, pose"]),
    ("sphere-radius-nan", "bad.yaml", _obstacle("{type: sphere, radius: .nan, center: [0, 0, 1]}"),
     ["problem 1 'b'", "obstacles[1].radius: must be a finite number, got nan"]),
    ("sphere-radius-zero", "bad.yaml", _obstacle("{type: sphere, radius: 0, center: [0, 0, 1]}"),
     ["problem 1 'b'", "obstacles[1].radius: must be > 0 m, got 0.0"]),
    ("sphere-center-short", "bad.yaml", _obstacle("{type: sphere, radius: 0.1, center: [0, 1]}"),
     ["problem 1 'b'", "obstacles[1].center: must be 3 numbers (x, y, z in m), got [0, 1]"]),
    ("sphere-pose", "bad.yaml", _obstacle("{type: sphere, radius: 0.1, center: [0, 0, 1], pose: {xyz: [0, 0, 0], rpy: [0, 0, 0]}}"),
     ["problem 1 'b'", "obstacles[1]: unknown key 'pose'; valid for a sphere: type, radius, center"]),
    ("cylinder-height-negative", "bad.yaml", _obstacle("{type: cylinder, radius: 0.1, height: -0.2, pose: {xyz: [0, 0, 0], rpy: [0, 0, 0]}}"),
     ["problem 1 'b'", "obstacles[1].height: must be > 0 m, got -0.2"]),
    ("cylinder-radius-inf", "bad.yaml", _obstacle("{type: cylinder, radius: .inf, height: 0.2, pose: {xyz: [0, 0, 0], rpy: [0, 0, 0]}}"),
     ["problem 1 'b'", "obstacles[1].radius: must be a finite number, got inf"]),
    ("box-size-zero", "bad.yaml", _box("{xyz: [0, 0, 0], rpy: [0, 0, 0]}", size="[0.1, 0, 0.1]"),
     ["problem 1 'b'", "obstacles[0].size: lengths must be > 0 m, got 0.0 along y"]),
    ("box-size-nan", "bad.yaml", _box("{xyz: [0, 0, 0], rpy: [0, 0, 0]}", size="[0.1, .nan, 0.1]"),
     ["problem 1 'b'", "obstacles[0].size[1]: must be a finite number, got nan"]),
    ("pose-both", "bad.yaml", _box("{xyz: [0, 0, 0], quat_xyzw: [0, 0, 0, 1], rpy: [0, 0, 0]}"),
     ["problem 1 'b'", "obstacles[0].pose: has both quat_xyzw and rpy; give the orientation once"]),
    ("pose-neither", "bad.yaml", _box("{xyz: [0, 0, 0]}"),
     ["problem 1 'b'", "obstacles[0].pose: has no orientation; give the orientation once: quat_xyzw"]),
    ("pose-no-xyz", "bad.yaml", _box("{rpy: [0, 0, 0]}"),
     ["problem 1 'b'", "obstacles[0].pose: missing 'xyz'"]),
    ("pose-unknown-key", "bad.yaml", _box("{xyz: [0, 0, 0], rpy: [0, 0, 0], frame: world}"),
     ["problem 1 'b'", "obstacles[0].pose: unknown key 'frame'; valid: xyz and one of quat_xyzw, rpy"]),
    ("pose-xyz-inf", "bad.yaml", _box("{xyz: [0, 0, -.inf], rpy: [0, 0, 0]}"),
     ["problem 1 'b'", "obstacles[0].pose.xyz[2]: must be a finite number, got -inf"]),
    ("pose-rpy-text", "bad.yaml", _box("{xyz: [0, 0, 0], rpy: [0, '90deg', 0]}"),
     ["problem 1 'b'", "obstacles[0].pose.rpy[1]: must be a number, got '90deg'"]),
    ("quat-not-unit", "bad.yaml", _box("{xyz: [0, 0, 0], quat_xyzw: [0, 0, 0, 2]}"),
     ["problem 1 'b'", "obstacles[0].pose.quat_xyzw: must be a unit quaternion (norm within 0.001 of 1), got norm 2"]),
    ("quat-zero", "bad.yaml", _box("{xyz: [0, 0, 0], quat_xyzw: [0, 0, 0, 0]}"),
     ["problem 1 'b'", "obstacles[0].pose.quat_xyzw: must be a unit quaternion", "got norm 0"]),
    ("quat-nan", "bad.yaml", _box("{xyz: [0, 0, 0], quat_xyzw: [0, 0, .nan, 1]}"),
     ["problem 1 'b'", "obstacles[0].pose.quat_xyzw[2]: must be a finite number, got nan"]),
    ("json-nan", "bad.json",
     json.dumps({"problems": [{"name": "j", "start": Q0, "goal": G1, "obstacles": []}]}).replace("0.0]", "NaN]", 1),
     ["problem 0 'j'", "start[5]: must be a finite number, got nan"]),
    ("json-syntax", "bad.json", '{"problems": [}', ["does not parse as JSON: line 1, column 15"]),
    ("yaml-syntax", "bad.yaml", "problems: [{start: [0, 0}\n", ["is not valid YAML: line 1"]),
    ("yaml-date", "bad.yaml", _with(name="2024-13-45"), ["is not valid YAML"]),
    ("empty", "bad.yaml", "", ["must be a mapping with a 'problems' list, got null"]),
    ("no-problems", "bad.yaml", "problems: []\n", ["needs a non-empty 'problems' list"]),
]  # fmt: skip


@pytest.mark.parametrize(
    ("name", "content", "fragments"),
    [
        pytest.param(name, content, fragments, id=case)
        for case, name, content, fragments in BAD_FILES
    ],
)
def test_bad_problem_files_name_the_file_the_problem_and_the_field(
    tmp_path: Path, name: str, content: str, fragments: list[str]
) -> None:
    path = _write(tmp_path, content, name)
    with pytest.raises(PlanningError) as caught:
        load_problems(path, dof=6)
    message = str(caught.value)
    assert "\n" not in message
    for fragment in [str(path), *fragments]:
        assert fragment in message, f"{fragment!r} not in {message!r}"


def _base() -> dict[str, Any]:
    pose = {"xyz": [0.3, 0.0, 0.1], "quat_xyzw": [0.0, 0.0, 0.0, 1.0]}
    return {
        "name": "p", "seed": 1, "start": list(Q0), "goal": [list(G1), list(G2)],
        "obstacles": [
            {"type": "box", "size": [0.1, 0.2, 0.3], "pose": pose},
            {"type": "sphere", "radius": 0.1, "center": [0.0, 0.5, 0.5]},
            {"type": "cylinder", "radius": 0.05, "height": 0.3, "pose": {"xyz": [0, 0, 0], "rpy": [0.1, 0.2, 0.3]}},
        ],
    }  # fmt: skip


SPOTS: list[tuple[str | int, ...]] = [
    ("name",), ("seed",), ("family",), ("difficulty",), ("start",), ("start", 2), ("goal",),
    ("goal", 1), ("goal", 1, 5), ("obstacles",), ("obstacles", 0), ("obstacles", 0, "type"),
    ("obstacles", 0, "size"), ("obstacles", 0, "size", 1), ("obstacles", 0, "pose"),
    ("obstacles", 0, "pose", "xyz"), ("obstacles", 0, "pose", "quat_xyzw"),
    ("obstacles", 0, "pose", "quat_xyzw", 3), ("obstacles", 0, "position"),
    ("obstacles", 1, "radius"), ("obstacles", 1, "center"), ("obstacles", 1, "center", 0),
    ("obstacles", 2, "height"), ("obstacles", 2, "pose", "rpy"), ("obstacles", 2, "pose", "rpy", 2),
]  # fmt: skip
VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=4),
    lambda inner: st.lists(inner, max_size=7) | st.dictionaries(st.text(max_size=4), inner, max_size=3),
    max_leaves=12,
)  # fmt: skip


@settings(max_examples=300, deadline=None)
@given(spot=st.sampled_from(SPOTS), value=VALUES)
def test_any_value_anywhere_loads_or_is_one_planning_error(
    spot: tuple[str | int, ...], value: Any
) -> None:
    item = _base()
    parent: Any = item
    for key in spot[:-1]:
        parent = parent[key]
    parent[spot[-1]] = value
    try:
        problem = problem_from_dict(item, "p.json: problem 0", dof=6)
    except PlanningError as err:
        assert str(err).startswith("p.json: problem 0") and "\n" not in str(err)
        return
    # what loads is what the file says, finite and of the robot's dof
    assert problem.start.shape == (6,) and problem.goals.shape[1] == 6
    assert np.isfinite(problem.start).all() and np.isfinite(problem.goals).all()
    assert len(problem.world) == len(item["obstacles"])


@settings(max_examples=25, deadline=None)
@given(
    goals=st.integers(1, 4),
    rpy=st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3),
    quat=st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
        lambda q: np.linalg.norm(q) > 0.1
    ),
)
def test_problems_round_trip_through_both_formats(
    goals: int, rpy: list[float], quat: list[float]
) -> None:
    rng = np.random.default_rng(goals)
    unit = (np.array(quat) / np.linalg.norm(quat)).tolist()
    item = _base()
    item["goal"] = rng.uniform(-3, 3, (goals, 6)).tolist()
    item["obstacles"][0]["pose"]["quat_xyzw"] = unit
    item["obstacles"][2]["pose"]["rpy"] = rpy
    problem = problem_from_dict(item, "p", dof=6)
    pts = rng.uniform(-1, 1, (100, 3))
    with tempfile.TemporaryDirectory() as folder:
        for name in ("p.yaml", "p.json"):
            save_problems(Path(folder) / name, [problem])
            (back,) = load_problems(Path(folder) / name, dof=6)
            np.testing.assert_array_equal(back.goals, problem.goals)
            np.testing.assert_array_equal(back.start, problem.start)
            np.testing.assert_allclose(
                back.world.distance(pts), problem.world.distance(pts), atol=1e-9
            )


def test_an_obstacle_with_flat_position_keys_is_refused_not_put_at_the_origin(
    tmp_path: Path,
) -> None:
    # as other benchmarks write obstacles: position and orientation beside the size
    flat = {
        "type": "box",
        "size": [0.2, 0.2, 0.2],
        "position": [0.6, 0.0, 0.3],
        "orientation_quat_xyzw": [0.0, 0.0, 0.0, 1.0],
    }
    item = {"name": "flat", "start": Q0, "goal": G1, "obstacles": [flat]}
    path = _write(tmp_path, json.dumps({"problems": [item]}), "flat.json")
    with pytest.raises(PlanningError, match=r"flat\.json: problem 0 'flat': obstacles\[0\]: "):
        load_problems(path)
    # the same box written as problem files write it is 0.1 m deep around that position
    pose = {"xyz": flat["position"], "quat_xyzw": flat["orientation_quat_xyzw"]}
    item["obstacles"] = [{"type": "box", "size": flat["size"], "pose": pose}]
    path.write_text(json.dumps({"problems": [item]}))
    world = load_problems(path)[0].world
    assert world.distance(np.array([[0.6, 0.0, 0.3]]))[0] == pytest.approx(-0.1)


def test_rpy_poses_equal_their_quaternions(tmp_path: Path) -> None:
    rpy = [0.3, -0.7, 1.9]  # rad, about the fixed x, y, z axes
    rx, ry, rz = (Rotation.from_rotvec(a * np.eye(3)[i]).as_matrix() for i, a in enumerate(rpy))
    R = rz @ ry @ rx  # URDF's convention, written out
    quat = Rotation.from_matrix(R).as_quat().tolist()
    xyz = [0.4, -0.2, 0.3]
    obstacles = [
        {"type": "box", "size": [0.3, 0.1, 0.05], "pose": {"xyz": xyz, "rpy": rpy}},
        {"type": "box", "size": [0.3, 0.1, 0.05], "pose": {"xyz": xyz, "quat_xyzw": quat}},
        {"type": "cylinder", "radius": 0.05, "height": 0.4, "pose": {"xyz": xyz, "rpy": rpy}},
        {"type": "cylinder", "radius": 0.05, "height": 0.4, "pose": {"xyz": xyz, "quat_xyzw": quat}},
    ]  # fmt: skip
    path = _write(
        tmp_path,
        yaml.safe_dump({"problems": [{"start": Q0, "goal": G1, "obstacles": obstacles}]}),
        "rpy.yaml",
    )
    prims = load_problems(path, dof=6)[0].world.primitives
    expected = np.eye(4)
    expected[:3, :3], expected[:3, 3] = R, xyz
    np.testing.assert_allclose(expected, from_xyz_rpy(xyz, rpy), atol=1e-12)
    for prim in prims:
        assert not isinstance(prim, Sphere)
        np.testing.assert_allclose(prim.pose, expected, atol=1e-12)
    pts = np.random.default_rng(0).uniform(-1, 1, (300, 3))
    for by_rpy, by_quat in ((0, 1), (2, 3)):
        np.testing.assert_allclose(
            PrimitiveWorld([prims[by_rpy]]).distance(pts),
            PrimitiveWorld([prims[by_quat]]).distance(pts),
            atol=1e-12,
        )
    # a quarter turn of yaw takes the box's long local x axis onto the world's y axis
    text = _box("{xyz: [0, 0, 0], rpy: [0, 0, 1.5707963267948966]}", size="[0.4, 0.1, 0.1]")
    turned = load_problems(_write(tmp_path, text), dof=6)[1].world
    assert turned.distance(np.array([[0.0, 0.19, 0.0], [0.19, 0.0, 0.0]])) == pytest.approx(
        [-0.01, 0.14]
    )


def test_a_nearly_unit_quaternion_is_normalized(tmp_path: Path) -> None:
    q = np.array([0.1, 0.2, 0.3, 0.9])
    q /= np.linalg.norm(q)
    off = (q * 1.0008).tolist()  # within the 1e-3 tolerance
    text = _box(f"{{xyz: [0, 0, 0], quat_xyzw: {off}}}")
    box = load_problems(_write(tmp_path, text), dof=6)[1].world.primitives[0]
    assert isinstance(box, Box)
    np.testing.assert_allclose(box.pose[:3, :3], Rotation.from_quat(q).as_matrix(), atol=1e-12)


def test_several_goals_load_and_round_trip(tmp_path: Path) -> None:
    text = (
        "problems:\n"
        f"  - {{name: one, start: {Q0}, goal: {G1}, obstacles: []}}\n"
        f"  - name: three\n    start: {Q0}\n    goal:\n"
        f"      - {G1}\n      - {G2}\n      - {OUT_OF_LIMITS}\n"
        f"    obstacles: [{FAR_SPHERE}]\n"
    )
    one, three = load_problems(_write(tmp_path, text, "goals.yaml"), dof=6)
    assert one.goals.shape == (1, 6) and three.goals.shape == (3, 6)
    np.testing.assert_array_equal(three.goals, [G1, G2, OUT_OF_LIMITS])
    np.testing.assert_array_equal(three.goal, G1)  # single-goal callers get the first
    assert one.to_dict()["goal"] == G1  # one goal stays one vector
    assert three.to_dict()["goal"] == [G1, G2, OUT_OF_LIMITS]
    for name in ("back.yaml", "back.json"):
        save_problems(tmp_path / name, [one, three])
        back = load_problems(tmp_path / name, dof=6)
        for p, q in zip((one, three), back, strict=True):
            assert q.name == p.name
            np.testing.assert_array_equal(q.goals, p.goals)
            np.testing.assert_array_equal(q.start, p.start)
    # without the robot's dof the start's length is the dof, which every goal must share
    assert load_problems(tmp_path / "back.json")[1].goals.shape == (3, 6)
    moved = replace(three, start=np.array(G2))
    np.testing.assert_array_equal(moved.goals, three.goals)
    with pytest.raises(PlanningError, match="give goal or goals"):
        Problem("x", "custom", 0, one.world, Q0, G1, goals=[G1])
    with pytest.raises(PlanningError, match=r"goals \(K >= 1, dof\)"):
        Problem("x", "custom", 0, one.world, Q0, goals=[[0.0, 1.0]])


def test_a_path_to_the_second_goal_passes_the_check(
    robot: RobotModel, spheres: SphereModel
) -> None:
    world = PrimitiveWorld([Sphere(0.05, np.array([2.0, 2.0, 2.0]))])
    start, goals = np.array(Q0), np.array([G1, G2])
    path = np.stack([start, goals[1]])
    assert check_path(path, start, goals, robot, spheres, world).ok
    assert not check_path(path, start, goals[0], robot, spheres, world).ok
    elsewhere = np.stack([start, (goals[0] + goals[1]) / 2])
    detail = check_path(elsewhere, start, goals, robot, spheres, world).detail
    assert detail == "path does not start at the start and end at one of the 2 goals"


def _goals_spec(goals: list[list[float]]) -> dict[str, object]:
    return {
        "name": "goals", "family": "custom", "seed": 3, "difficulty": "", "start": Q0,
        "goal": goals, "obstacles": [{"type": "sphere", "radius": 0.05, "center": [2, 2, 2]}],
    }  # fmt: skip


def test_the_harness_hands_every_valid_goal_to_rrtc() -> None:
    harness._init_worker(None)
    spec = _goals_spec([OUT_OF_LIMITS, G2, G1])
    rec = harness._run((spec, "rrtc", 5.0, False, "compiled"))
    assert rec.success and rec.status == "success", rec.detail
    # all goals invalid: counted apart, as a single invalid goal is
    rec = harness._run((_goals_spec([OUT_OF_LIMITS, OUT_OF_LIMITS]), "rrtc", 1.0, False, "compiled"))  # fmt: skip
    assert rec.status == "goal_invalid" and rec.detail.startswith("all 2 goals are invalid; goal 0")


def test_the_harness_gives_many_goal_planners_all_and_others_the_nearest(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    seen: dict[str, np.ndarray] = {}

    class ManyGoals:
        name = "many"

        def plan(self, checker, start, goal, *, budget_s, rng):  # type: ignore[no-untyped-def]
            raise AssertionError("a planner with plan_between gets every goal at once")

        def plan_between(self, checker, starts, goals, *, budget_s, rng):  # type: ignore[no-untyped-def]
            seen["many"] = goals
            path = np.stack([starts[0], goals[-1]])
            return PlanResult("many", PlanStatus.SUCCESS, path, 0.01)

    class OneGoal:
        name = "one"

        def plan(self, checker, start, goal, *, budget_s, rng):  # type: ignore[no-untyped-def]
            seen["one"] = goal
            return PlanResult("one", PlanStatus.SUCCESS, np.stack([start, goal]), 0.01)

    harness._init_worker(None)
    spec = _goals_spec([G1, OUT_OF_LIMITS, G2])
    for planner in (ManyGoals(), OneGoal()):
        monkeypatch.setattr(harness, "make_planner", lambda name, p=planner, **_: p)
        rec = harness._run((spec, planner.name, 1.0, False, "compiled"))
        assert rec.success, rec.detail
    np.testing.assert_array_equal(seen["many"], [G1, G2])  # the valid goals, all of them
    # the valid goal nearest the start in joint space: G2 is 0.45 rad away, G1 0.5
    np.testing.assert_array_equal(seen["one"], G2)


@pytest.mark.parametrize(
    ("content", "fragment"),
    [
        pytest.param(
            b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "is a binary file, not text", id="binary"
        ),
        pytest.param(
            "problems: [{name: caf\u00e9}]".encode("latin-1"),
            "is not UTF-8 text (byte 21: b'\\xe9')",
            id="latin-1",
        ),
    ],
)
def test_binary_and_non_utf8_files_are_one_error_line(
    tmp_path: Path, content: bytes, fragment: str
) -> None:
    path = _write(tmp_path, content, "weird.yaml")
    with pytest.raises(PlanningError) as caught:
        load_problems(path, dof=6)
    assert fragment in str(caught.value) and str(path) in str(caught.value)
    assert "\n" not in str(caught.value)


BILLION_LAUGHS = "\n".join(
    [
        'a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]',
        *(
            f"{c}: &{c} [{', '.join([f'*{p}'] * 9)}]"
            for p, c in zip("abcdefgh", "bcdefghi", strict=True)
        ),
        "problems: *i",
    ]
)


@pytest.mark.parametrize("loader", ["libyaml", "python"])
def test_alias_bombs_and_deep_nesting_are_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, loader: str
) -> None:
    if loader == "python":  # the fallback without libyaml refuses the same files
        import gaide_core.text_io

        monkeypatch.setattr(gaide_core.text_io, "_Loader", yaml.SafeLoader)
    cases = [
        (BILLION_LAUGHS, "aliases expand to more than 1,000,000 nodes"),
        ("problems: &p [*p]\n", "alias *p (line 1) names no anchor before it"),
        ("problems: " + "[" * 100_000 + "]" * 100_000, "nests deeper than 32 levels"),
    ]
    for text, fragment in cases:
        path = _write(tmp_path, text, "bomb.yaml")
        with pytest.raises(PlanningError) as caught:
            load_problems(path, dof=6)
        assert fragment in str(caught.value) and str(path) in str(caught.value)
        assert "\n" not in str(caught.value)
    # anchors and aliases within the limits are YAML as usual: one scene shared
    text = (
        "problems:\n"
        f"  - {{name: a, start: {Q0}, goal: {G1}, obstacles: &scene [{FAR_SPHERE}]}}\n"
        f"  - {{name: b, start: {Q0}, goal: {G2}, obstacles: *scene}}\n"
    )
    a, b = load_problems(_write(tmp_path, text, "aliases.yaml"), dof=6)
    assert len(a.world) == len(b.world) == 1


def test_the_size_limit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(problem_module, "MAX_FILE_BYTES", 2**20)
    path = _write(tmp_path, "problems:\n" + GOOD * 20_000, "big.yaml")
    with pytest.raises(
        PlanningError, match=r"big\.yaml is [0-9,]+ bytes; the largest accepted is 1,048,576"
    ):
        load_problems(path, dof=6)


def test_cli_refuses_a_bad_problem_file_in_one_line_and_writes_nothing(tmp_path: Path) -> None:
    bad = _write(tmp_path, _with(start="[0, 0, .nan, 0, 0, 0]"), "bad.yaml")
    out = tmp_path / "out.json"
    proc = run_cli(
        "bench", "planning", "--problem-file", str(bad), "--planners", "rrtc", "--json", str(out)
    )
    assert proc.returncode == 7, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert f"{bad}: problem 1 'b': start[2]: must be a finite number, got nan" in lines[0]
    assert proc.stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.yaml"]
