"""Problems from MoveIt's planning-scene and motion-plan-request YAML, the layout of
MotionBenchMaker's benchmark sets (and of the sets other planners ship from it).

A set is a folder of pairs ``sceneNNNN.yaml`` (a ``moveit_msgs/PlanningScene``: its
``world.collision_objects``) and ``requestNNNN.yaml`` (a ``moveit_msgs/MotionPlanRequest``:
``start_state.joint_state`` and ``goal_constraints``); pair NNNN becomes the problem
``<folder>-NNNN`` of family ``<folder>``, with seed NNNN.

What is read, as MoveIt means it:
- a collision object's ``primitives[i]`` sits at ``primitive_poses[i]``, in the object's
  ``pose`` when it has one (MoveIt >= 1.1), all in the scene's planning frame, which must be
  the robot config's world frame (``base_pose`` places the robot in it);
- a box's ``dimensions`` are its three edge lengths, a cylinder's [height, radius] (along
  its z axis), a sphere's [radius]; a pose's ``orientation`` is a quaternion [x, y, z, w]
  (a list or an x/y/z/w mapping), its ``position`` a list or an x/y/z mapping;
- each entry of ``goal_constraints`` is one goal (MoveIt is satisfied by any of them), given
  by its ``joint_constraints``; joints the robot does not plan (a gripper's) are ignored.

Meshes, cones, planes, objects in another frame or attached to the robot, and pose goals are
not problems the harness can run: they are refused with a line that names the file and the
object, as is any other malformed entry.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from gaide_core.errors import PlanningError
from gaide_core.text_io import load_yaml
from gaide_core.transforms import to_xyz_quat
from gaide_core.types import Array
from planning.primitives import PrimitiveWorld, number, parse_pose, show
from planning.problem import Problem

_PAIR = re.compile(r"^(scene|request)(\d+)\.ya?ml$")
_SHAPES = {"box": "[x, y, z] edge lengths", "cylinder": "[height, radius]", "sphere": "[radius]"}
_UNSUPPORTED = ("meshes", "mesh_poses", "planes", "plane_poses")
# Frame names that mean the scene's planning frame (MotionBenchMaker's objects give none).
_PLANNING_FRAMES = ("", "world", "/world")


def import_moveit_set(folder: str | Path, joint_names: tuple[str, ...]) -> list[Problem]:
    """The problems of one MotionBenchMaker-style folder (module docstring), in the order of
    their numbers, for a robot planning ``joint_names``."""
    root = Path(folder)
    if not root.is_dir():
        raise PlanningError(f"{root}: not a folder; give a folder of sceneNNNN.yaml and "
                            "requestNNNN.yaml pairs (MotionBenchMaker's layout)")  # fmt: skip
    files: dict[str, dict[int, Path]] = {"scene": {}, "request": {}}
    for path in root.iterdir():
        match = _PAIR.match(path.name)
        if match:
            files[match.group(1)][int(match.group(2))] = path
    scenes, requests = files["scene"], files["request"]
    if not scenes and not requests:
        raise PlanningError(
            f"{root}: no sceneNNNN.yaml / requestNNNN.yaml files; a MotionBenchMaker set "
            "holds one pair per problem"
        )
    unpaired = sorted(set(scenes) ^ set(requests))
    if unpaired:
        n = unpaired[0]
        have, lacks = ("scene", "request") if n in scenes else ("request", "scene")
        raise PlanningError(
            f"{root}: {have}{n:04d} has no {lacks} file; every problem is a scene and a "
            "request with the same number"
        )
    family = root.name
    return [_problem(family, n, scenes[n], requests[n], joint_names) for n in sorted(scenes)]


def import_moveit_sets(
    folders: list[str] | list[Path], joint_names: tuple[str, ...]
) -> list[Problem]:
    """The problems of several folders (:func:`import_moveit_set`), in the order given. A
    folder's name is its family and its problems' name prefix, so two folders of one name
    (``a/cage`` and ``b/cage``) are refused: their problems' names would collide."""
    seen: dict[str, Path] = {}
    for folder in map(Path, folders):
        if folder.name in seen:
            raise PlanningError(
                f"{folder} and {seen[folder.name]} have the same name; each folder becomes the "
                "family of that name, so give folders with distinct names"
            )
        seen[folder.name] = folder
    return [p for folder in seen.values() for p in import_moveit_set(folder, joint_names)]


def _problem(
    family: str, n: int, scene: Path, request: Path, joint_names: tuple[str, ...]
) -> Problem:
    obstacles = scene_obstacles(load_yaml(scene, "MoveIt scene", PlanningError), str(scene))
    start, goals = request_joints(
        load_yaml(request, "MoveIt request", PlanningError), str(request), joint_names
    )
    world = PrimitiveWorld.from_dict(obstacles)
    return Problem(f"{family}-{n:04d}", family, n, world, start, goals=goals)


def scene_obstacles(scene: Any, where: str) -> list[dict[str, Any]]:
    """The collision objects of a PlanningScene mapping as obstacles in the problem-file
    layout (:mod:`planning.primitives`), in the scene's planning frame."""
    world = _get(scene, "world", where)
    if not isinstance(world, dict):
        raise PlanningError(f"{where}: world must be a mapping, got {show(world)}")
    state = scene.get("robot_state")
    if isinstance(state, dict) and state.get("attached_collision_objects"):
        raise PlanningError(
            f"{where}: robot_state has attached collision objects; a problem's obstacles are "
            "fixed in the world, so only world.collision_objects can be imported"
        )
    objects = world.get("collision_objects") or []
    if not isinstance(objects, list):
        raise PlanningError(f"{where}: world.collision_objects must be a list, got {show(objects)}")
    out: list[dict[str, Any]] = []
    for i, obj in enumerate(objects):
        here = f"{where}: collision_objects[{i}]"
        if not isinstance(obj, dict):
            raise PlanningError(f"{here}: must be a mapping, got {show(obj)}")
        here = f"{where}: collision object {show(obj.get('id', i))}"
        header = obj.get("header")
        frame = header.get("frame_id", "") if isinstance(header, dict) else ""
        if frame not in _PLANNING_FRAMES:
            raise PlanningError(
                f"{here}: is given in frame {show(frame)}; only objects in the planning frame "
                "('' or 'world') can be imported"
            )
        for key in _UNSUPPORTED:
            if obj.get(key):
                raise PlanningError(f"{here}: has {key}; only box, cylinder and sphere "
                                    "primitives can be imported")  # fmt: skip
        T_obj = _pose(obj["pose"], f"{here}.pose") if obj.get("pose") is not None else np.eye(4)
        prims, poses = obj.get("primitives") or [], obj.get("primitive_poses") or []
        if not isinstance(prims, list) or not isinstance(poses, list) or len(prims) != len(poses):
            raise PlanningError(
                f"{here}: primitives and primitive_poses must be lists of the same length, got "
                f"{show(prims)} and {show(poses)}"
            )
        for k, (prim, pose) in enumerate(zip(prims, poses, strict=True)):
            T = T_obj @ _pose(pose, f"{here}.primitive_poses[{k}]")
            out.append(_obstacle(prim, T, f"{here}.primitives[{k}]"))
    return out


def _obstacle(prim: Any, T: Array, where: str) -> dict[str, Any]:
    kind = prim.get("type") if isinstance(prim, dict) else None
    if kind not in _SHAPES:
        valid = ", ".join(f"{k} {v}" for k, v in _SHAPES.items())
        raise PlanningError(f"{where}: type {show(kind)} cannot be imported; valid: {valid}")
    dims = prim.get("dimensions")
    want = 3 if kind == "box" else 2 if kind == "cylinder" else 1
    if not isinstance(dims, list) or len(dims) != want:
        raise PlanningError(f"{where}: a {kind}'s dimensions are {_SHAPES[kind]}, got {show(dims)}")
    d = [number(v, f"{where}.dimensions") for v in dims]
    if min(d) <= 0:
        raise PlanningError(f"{where}: a {kind}'s dimensions must be > 0 m, got {d}")
    xyz, quat = to_xyz_quat(T)
    pose = {"xyz": xyz.tolist(), "quat_xyzw": quat.tolist()}
    if kind == "box":
        return {"type": "box", "size": d, "pose": pose}
    if kind == "cylinder":
        return {"type": "cylinder", "radius": d[1], "height": d[0], "pose": pose}
    return {"type": "sphere", "radius": d[0], "center": xyz.tolist()}


def _pose(raw: Any, where: str) -> Array:
    """T (4, 4) of a geometry_msgs/Pose mapping: position and orientation as lists or
    x/y/z(/w) mappings; a missing orientation is the identity."""
    if not isinstance(raw, dict) or "position" not in raw:
        raise PlanningError(f"{where}: a pose is {{position: [x, y, z], orientation: [x, y, "
                            f"z, w]}}, got {show(raw)}")  # fmt: skip
    xyz = _vector(raw["position"], "xyz", f"{where}.position")
    quat = _vector(raw.get("orientation", [0, 0, 0, 1]), "xyzw", f"{where}.orientation")
    return parse_pose({"xyz": xyz, "quat_xyzw": quat}, where)


def _vector(raw: Any, axes: str, where: str) -> Any:
    if isinstance(raw, dict):
        missing = [a for a in axes if a not in raw]
        if missing:
            raise PlanningError(f"{where}: missing {', '.join(missing)}; give {', '.join(axes)}")
        return [raw[a] for a in axes]
    return raw


def request_joints(request: Any, where: str, joint_names: tuple[str, ...]) -> tuple[Array, Array]:
    """(start (dof,), goals (K, dof)) of a MotionPlanRequest mapping, in the order of
    ``joint_names``."""
    state = _get(_get(request, "start_state", where), "joint_state", f"{where}: start_state")
    names = _get(state, "name", f"{where}: start_state.joint_state")
    values = _get(state, "position", f"{where}: start_state.joint_state")
    if not isinstance(names, list) or not isinstance(values, list) or len(names) != len(values):
        raise PlanningError(
            f"{where}: start_state.joint_state needs name and position lists of the same "
            f"length, got {show(names)} and {show(values)}"
        )
    start = _pick(dict(zip(names, values, strict=True)), joint_names, f"{where}: start_state")
    sets = _get(request, "goal_constraints", where)
    if not isinstance(sets, list) or not sets:
        raise PlanningError(f"{where}: goal_constraints must list at least one goal, got "
                            f"{show(sets)}")  # fmt: skip
    goals = []
    for i, goal in enumerate(sets):
        here = f"{where}: goal_constraints[{i}]"
        joints = goal.get("joint_constraints") if isinstance(goal, dict) else None
        if not isinstance(joints, list) or not joints:
            raise PlanningError(
                f"{here}: only joint goals can be imported (joint_constraints), got {show(goal)}"
            )
        pairs = {}
        for c in joints:
            if not isinstance(c, dict) or "joint_name" not in c or "position" not in c:
                raise PlanningError(f"{here}: a joint constraint needs joint_name and "
                                    f"position, got {show(c)}")  # fmt: skip
            pairs[c["joint_name"]] = c["position"]
        goals.append(_pick(pairs, joint_names, here))
    return np.array(start), np.array(goals)


def _pick(values: dict[Any, Any], joint_names: tuple[str, ...], where: str) -> list[float]:
    missing = [j for j in joint_names if j not in values]
    if missing:
        raise PlanningError(
            f"{where}: no value for joint {missing[0]}; the robot plans {', '.join(joint_names)}"
        )
    return [number(values[j], f"{where}.{j}") for j in joint_names]


def _get(mapping: Any, key: str, where: str) -> Any:
    if not isinstance(mapping, dict):
        raise PlanningError(f"{where}: must be a mapping, got {show(mapping)}")
    if key not in mapping:
        raise PlanningError(f"{where}: missing '{key}'")
    return mapping[key]
