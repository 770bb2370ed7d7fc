"""Writing trajectories and joint logs in the format each output path names.

A trajectory: ``.csv`` and ``.json`` (:mod:`execution.trajectory_io`), ``.bag`` (ROS1) and a
suffix-less path (a ROS2 bag folder, ``storage`` sqlite3 or mcap) holding one
``trajectory_msgs/JointTrajectory`` (:mod:`execution.ros_bags`). A joint log: ``.csv``
(:mod:`execution.joint_log`), ``.bag`` or a ROS2 folder of ``sensor_msgs/JointState``.

Every output is written to a temporary sibling first and all are renamed into place only
when all were written (:func:`gaide_core.atomic.write_files_atomic`): on any error nothing is
left half-written, and no output of the call is created.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from execution.joint_log import log_csv
from execution.ros_bags import ros_version_of, write_joint_state_bag, write_trajectory_bag
from execution.trajectory import TimedTrajectory
from execution.trajectory_io import trajectory_csv, trajectory_json
from gaide_core.atomic import Content, write_files_atomic
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates

TRAJECTORY_FORMATS = ".csv, .json, .bag (ROS1) or a folder name without a suffix (ROS2)"
LOG_FORMATS = ".csv, .bag (ROS1) or a folder name without a suffix (ROS2)"


def check_trajectory_outputs(paths: Sequence[str | Path]) -> list[Path]:
    """The paths as Paths, or ExecutionError naming one whose format is unknown (call it
    before long work, so that a typo fails at once)."""
    return _check(paths, (".csv", ".json", ".bag", ""), TRAJECTORY_FORMATS)


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


def write_trajectory(
    traj: TimedTrajectory,
    paths: Sequence[str | Path],
    *,
    storage: str = "sqlite3",
    extra: Mapping[Path, bytes] | None = None,
) -> list[Path]:
    """Write ``traj`` to every path, each in the format its suffix names, and the ``extra``
    files (path -> bytes: a plot, a report) in the same all-or-nothing step."""

    def content(target: Path) -> Content:
        if target.suffix == ".csv":
            return trajectory_csv(traj).encode()
        if target.suffix == ".json":
            return trajectory_json(traj).encode()
        version = ros_version_of(target)
        return lambda tmp: write_trajectory_bag(traj, tmp, ros_version=version, storage=storage)

    return _write_all(check_trajectory_outputs(paths), extra, content)


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
