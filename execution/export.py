"""Writing trajectories and joint logs in the format each output path names.

A trajectory: ``.csv`` and ``.json`` (:mod:`execution.trajectory_io`), ``.bag`` (ROS1) and a
suffix-less path (a ROS2 bag folder, ``storage`` sqlite3 or mcap) holding one
``trajectory_msgs/JointTrajectory`` (:mod:`execution.ros_bags`), ``.script`` (a URScript
program, :mod:`execution.urscript`) and ``.yaml``/``.yml`` (a ros2_control
``FollowJointTrajectory`` goal, :mod:`execution.ros2_goal`). A joint log: ``.csv``
(:mod:`execution.joint_log`), ``.bag`` or a ROS2 folder of ``sensor_msgs/JointState``.

Every output is written to a temporary sibling first and all are renamed into place only
when all were written (:func:`gaide_core.atomic.write_files_atomic`): on any error nothing is
left half-written, and no output of the call is created. Given the robot, a trajectory of
other joints (names or order) is refused before anything is written.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from execution.joint_log import log_csv
from execution.ros2_goal import Ros2GoalCfg, goal_yaml
from execution.ros_bags import ros_version_of, write_joint_state_bag, write_trajectory_bag
from execution.trajectory import TimedTrajectory
from execution.trajectory_io import trajectory_csv, trajectory_json
from execution.urscript import UrScriptCfg, UrScriptMode, urscript_program
from gaide_core.atomic import Content, write_files_atomic
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates

if TYPE_CHECKING:
    from planning.robot_model import RobotModel

TRAJECTORY_FORMATS = (
    ".csv, .json, .bag (ROS1), a folder name without a suffix (ROS2), .script (URScript) or "
    ".yaml/.yml (ros2_control FollowJointTrajectory goal)"
)
TRAJECTORY_SUFFIXES = (".csv", ".json", ".bag", "", ".script", ".yaml", ".yml")
LOG_FORMATS = ".csv, .bag (ROS1) or a folder name without a suffix (ROS2)"


def check_trajectory_outputs(paths: Sequence[str | Path]) -> list[Path]:
    """The paths as Paths, or ExecutionError naming one whose format is unknown (call it
    before long work, so that a typo fails at once)."""
    return _check(paths, TRAJECTORY_SUFFIXES, TRAJECTORY_FORMATS)


def check_log_outputs(paths: Sequence[str | Path]) -> list[Path]:
    """As :func:`check_trajectory_outputs`, for joint logs (none is fine)."""
    return _check(paths, (".csv", ".bag", ""), LOG_FORMATS) if paths else []


def _check(paths: Sequence[str | Path], allowed: tuple[str, ...], formats: str) -> list[Path]:
    out = [Path(p) for p in paths]
    if not out:
        raise ExecutionError(f"no output given; formats: {formats}")
    for p in out:
        if p.suffix not in allowed:
            raise ExecutionError(f"{p}: unknown output format '{p.suffix}'; valid: {formats}")
    return out


def check_joints(names: Sequence[str], robot: RobotModel, what: str = "the trajectory") -> None:
    """ExecutionError unless ``names`` are the robot's joints, in its order."""
    if tuple(names) != tuple(robot.joint_names):
        raise ExecutionError(
            f"{what}: joints {list(names)} are not the robot's {list(robot.joint_names)} "
            "(same names, same order); give the robot config it was made for (--robot)"
        )


def write_trajectory(
    traj: TimedTrajectory,
    paths: Sequence[str | Path],
    *,
    storage: str = "sqlite3",
    extra: Mapping[Path, bytes] | None = None,
    urscript: UrScriptCfg | None = None,
    goal: Ros2GoalCfg | None = None,
    robot: RobotModel | None = None,
) -> list[Path]:
    """Write ``traj`` to every path, each in the format its suffix names, and the ``extra``
    files (path -> bytes: a plot, a report) in the same all-or-nothing step. ``urscript`` and
    ``goal`` set the URScript program and the ros2_control goal (defaults: their classes');
    ``robot``, when given, must have the trajectory's joints, and gives the tool positions
    that movej's blend radii need."""
    targets = check_trajectory_outputs(paths)
    if robot is not None:
        check_joints(traj.joint_names, robot)

    def content(target: Path) -> Content:
        if target.suffix == ".csv":
            return trajectory_csv(traj).encode()
        if target.suffix == ".json":
            return trajectory_json(traj).encode()
        if target.suffix == ".script":
            return _program(traj, urscript or UrScriptCfg(), robot).encode()
        if target.suffix in (".yaml", ".yml"):
            return goal_yaml(traj, goal, file_name=target.name).encode()
        version = ros_version_of(target)
        return lambda tmp: write_trajectory_bag(traj, tmp, ros_version=version, storage=storage)

    return _write_all(targets, extra, content)


def _program(traj: TimedTrajectory, cfg: UrScriptCfg, robot: RobotModel | None) -> str:
    tool = None
    if cfg.urscript_mode is UrScriptMode.MOVEJ and robot is not None and traj.path is not None:
        tool = np.array([robot.frame_pose(q)[:3, 3] for q in traj.path])
    return urscript_program(traj, cfg, tool_xyz=tool)


def write_log(
    joint_log: JointStates,
    paths: Sequence[str | Path],
    *,
    storage: str = "sqlite3",
    extra: Mapping[Path, bytes] | None = None,
) -> list[Path]:
    """Write ``joint_log`` to every path, each in the format its suffix names, and the
    ``extra`` files (path -> bytes) in the same all-or-nothing step."""

    def content(target: Path) -> Content:
        if target.suffix == ".csv":
            return log_csv(joint_log).encode()
        version = ros_version_of(target)
        return lambda tmp: write_joint_state_bag(
            joint_log, tmp, ros_version=version, storage=storage
        )

    return _write_all(check_log_outputs(paths), extra, content)


def _write_all(
    targets: list[Path],
    extra: Mapping[Path, bytes] | None,
    content: Callable[[Path], Content],
) -> list[Path]:
    """Every target's ``content(target)`` and the ``extra`` bytes, written together."""
    write_files_atomic(
        [*((target, content(target)) for target in targets), *(extra or {}).items()],
        ExecutionError,
    )
    return targets


def read_log(path: str | Path, topic: str | None = None) -> JointStates:
    """A joint log from a CSV file (this project's or ``rostopic echo -p``'s) or a bag."""
    from execution.joint_log import read_log_csv
    from execution.ros_bags import read_joint_state_bag

    source = Path(path)
    if source.suffix == ".csv":
        return read_log_csv(source)
    return read_joint_state_bag(source, topic)
