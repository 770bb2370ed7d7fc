"""A timed trajectory as a ros2_control ``FollowJointTrajectory`` goal in YAML, for::

    ros2 action send_goal /joint_trajectory_controller/follow_joint_trajectory \\
        control_msgs/action/FollowJointTrajectory "$(cat goal.yaml)"

which the file's first line says, with its controller (``ros2_controller``) and name. The
goal is ``trajectory: {joint_names, points}`` (the URDF's joint names; each point ``positions`` rad,
``velocities`` rad/s, ``accelerations`` rad/s^2 and ``time_from_start: {sec, nanosec}``,
rounded to the nanosecond) and ``goal_time_tolerance: {sec, nanosec}``. The header is left
out (stamp 0: the controller starts the trajectory when it accepts it), and so are the
tolerances (the controller's own apply). The first point is the start at t = 0: the robot
must be there.

Points are the trajectory's samples, every k-th (at most ``goal_rate_hz`` per second) and the
last: ros2_control's ``joint_trajectory_controller`` joins points that carry positions,
velocities and accelerations with quintic splines, which follow a jerk-limited trajectory
closely between samples (within 2e-6 rad at 50 Hz on a UR5 trajectory at its limits), and the
whole goal must pass as one shell argument: Linux takes at most 128 KiB in one
(``MAX_ARG_STRLEN``), about 300 points. A longer goal is written with a warning naming the
rate that fits.

Numbers are Python's shortest round-trip form (exact doubles) with a '.' in every exponent
form, as YAML 1.1 readers (PyYAML, which ``ros2 action send_goal`` uses) need to read a float.
"""

from __future__ import annotations

import json
import logging
import math
import re
import shlex
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from execution.timing_cfg import MAX_RATE_HZ
from gaide_core import settings
from gaide_core.errors import ExecutionError

if TYPE_CHECKING:  # light to import: `gaide time` shows these defaults in its help
    from execution.trajectory import TimedTrajectory

log = logging.getLogger(__name__)

#: bytes: Linux's limit on one command-line argument (MAX_ARG_STRLEN, 32 pages of 4 KiB)
MAX_ARG_BYTES = 128 * 1024
ACTION_TYPE = "control_msgs/action/FollowJointTrajectory"
_ROS_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")


@dataclass(frozen=True, kw_only=True)
class Ros2GoalCfg:
    """Settings of :func:`goal_yaml`."""

    ros2_controller: str = "joint_trajectory_controller"  # /<it>/follow_joint_trajectory
    goal_rate_hz: float = 50.0  # Hz, points per second at most (every k-th sample, and the last)
    goal_time_tolerance_s: float = 0.5  # s, how late after the end the goal may be reached

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        err = ExecutionError
        name = self.ros2_controller
        if not isinstance(name, str) or not _ROS_NAME.fullmatch(name):
            raise err(
                "ros2_controller must be a ROS name (letters, digits, '_', namespaces with '/'; "
                f"e.g. scaled_joint_trajectory_controller), got {name!r}"
            )
        put(
            "goal_rate_hz",
            settings.number(
                self.goal_rate_hz, "goal_rate_hz", lo=1.0, hi=MAX_RATE_HZ, unit="Hz", error=err
            ),
        )
        put(
            "goal_time_tolerance_s",
            settings.number(
                self.goal_time_tolerance_s, "goal_time_tolerance_s", lo=0.0, hi=60.0, unit="s",
                error=err,
            ),
        )  # fmt: skip

    @property
    def action(self) -> str:
        return f"/{self.ros2_controller}/follow_joint_trajectory"


def send_goal_command(cfg: Ros2GoalCfg, file_name: str) -> str:
    """The shell command that sends the goal file ``file_name`` (its path as given)."""
    return f'ros2 action send_goal {cfg.action} {ACTION_TYPE} "$(cat {shlex.quote(file_name)})"'


def goal_points(traj: TimedTrajectory, rate_hz: float) -> npt.NDArray[np.int64]:
    """Indices of the samples the goal holds: every k-th, k the smallest step that keeps
    at most ``rate_hz`` points per second, and the last."""
    n = len(traj.t)
    step = max(1, math.ceil(traj.rate_hz / rate_hz - 1e-9))
    idx = np.arange(0, n, step, dtype=np.int64)
    return idx if idx[-1] == n - 1 else np.append(idx, np.int64(n - 1))


def nanoseconds(seconds: float) -> tuple[int, int]:
    """``(sec, nanosec)`` of a ``builtin_interfaces/Duration``, rounded to the nanosecond."""
    ns = round(seconds * 1e9)
    return ns // 10**9, ns % 10**9


def goal_yaml(
    traj: TimedTrajectory, cfg: Ros2GoalCfg | None = None, *, file_name: str = "goal.yaml"
) -> str:
    """The goal file's text (module doc); its first line is the command for ``file_name``."""
    cfg = cfg or Ros2GoalCfg()
    idx = goal_points(traj, cfg.goal_rate_hz)
    for what in ("q", "qd", "qdd"):
        if not np.all(np.isfinite(getattr(traj, what)[idx])):
            raise ExecutionError(f"the trajectory holds NaN or inf in {what}")
    step = int(idx[1] - idx[0]) if len(idx) > 1 else 1
    lines = [
        f"# {send_goal_command(cfg, file_name)}",
        f"# A {ACTION_TYPE} goal for ros2_control's joint_trajectory_controller (gaide):",
        f"# {traj.duration:.3f} s in {len(idx)} points: the trajectory's {traj.rate_hz:g} Hz "
        f"samples every {step / traj.rate_hz:g} s and the last,",
        "# joined by the controller with quintic splines. Units: rad, rad/s, rad/s^2.",
        "# The robot must be at the first point.",
        "trajectory:",
        "  joint_names: [" + ", ".join(json.dumps(n) for n in traj.joint_names) + "]",
        "  points:",
        *(_point(traj, int(i)) for i in idx),
        f"goal_time_tolerance: {_duration(cfg.goal_time_tolerance_s)}",
        "",
    ]
    text = "\n".join(lines)
    size = len(text.encode())
    if size >= MAX_ARG_BYTES:
        fits = cfg.goal_rate_hz * 0.9 * MAX_ARG_BYTES / size
        log.warning(
            "%s is %d KiB, more than one shell argument holds (128 KiB): `ros2 action "
            "send_goal ... \"$(cat %s)\"` would fail; lower goal_rate_hz (`gaide time "
            "--goal-rate`) to %.0f Hz or less",
            file_name, size // 1024, file_name, math.floor(fits),
        )  # fmt: skip
    return text


def _point(traj: TimedTrajectory, i: int) -> str:
    return (
        f"  - {{positions: {_list(traj.q[i])}, velocities: {_list(traj.qd[i])}, "
        f"accelerations: {_list(traj.qdd[i])}, time_from_start: {_duration(float(traj.t[i]))}}}"
    )


def _duration(seconds: float) -> str:
    sec, nanosec = nanoseconds(seconds)
    return f"{{sec: {sec}, nanosec: {nanosec}}}"


def _list(row: npt.NDArray[np.float64]) -> str:
    return "[" + ", ".join(_num(x) for x in row) + "]"


def _num(x: float) -> str:
    text = repr(float(x))
    if "e" in text and "." not in text:  # YAML 1.1 reads 1e-05 as a string, 1.0e-05 as a float
        text = text.replace("e", ".0e", 1)
    return text
