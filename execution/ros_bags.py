"""Trajectories and joint-state logs as ROS1 and ROS2 bags (rosbags; no ROS installation).

- A trajectory is one ``trajectory_msgs/msg/JointTrajectory`` message on
  ``/joint_trajectory``: the URDF's joint names, one point per sample with positions (rad),
  velocities (rad/s), accelerations (rad/s^2) and ``time_from_start``; the header stamp is 0
  (ROS: start on receipt) unless given.
- A joint-state log is one ``sensor_msgs/msg/JointState`` message per sample on
  ``/joint_states``, header stamps and log times equal (ns).

Paths: ``NAME.bag`` is a ROS1 bag (one file); any path without a suffix is a ROS2 bag (a
folder) with ``sqlite3`` (default) or ``mcap`` storage. Reading takes either, and a ``.mcap``
file. ROS1 bags carry full message definitions, ROS2 bags carry the type definitions in their
storage, so ROS tools decode them without this project. Messages and the writing are
:mod:`gaide_core.ros`'s (one bag writer for every package): a bag is written into a temporary
sibling and renamed into place.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, TypesysError, get_typestore

from execution.joint_log import check_log
from execution.trajectory import TimedTrajectory
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates
from gaide_core.ros import (
    JOINT_STATE,
    BagMessage,
    Messages,
    joint_state_messages,
    joint_states_from,
    message_stamp_ns,
    write_bag,
)

log = logging.getLogger(__name__)

TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
POINT = "trajectory_msgs/msg/JointTrajectoryPoint"
TRAJECTORY_TOPIC = "/joint_trajectory"
JOINT_STATES_TOPIC = "/joint_states"


def ros_version_of(path: str | Path) -> int:
    """1 for ``*.bag``, 2 for a suffix-less path (a ROS2 bag folder); ExecutionError else."""
    p = Path(path)
    if p.suffix == ".bag":
        return 1
    if p.suffix == "":
        return 2
    raise ExecutionError(
        f"{p}: a bag path is NAME.bag (ROS1) or a folder name without a suffix (ROS2)"
    )


def write_trajectory_bag(
    traj: TimedTrajectory,
    path: str | Path,
    *,
    ros_version: int | None = None,
    storage: str = "sqlite3",
    topic: str = TRAJECTORY_TOPIC,
    stamp_ns: int = 0,
) -> Path:
    """Write ``traj`` as one JointTrajectory message into a new bag at ``path`` (ROS version
    from the path unless given; ``stamp_ns`` is the header stamp, 0: start on receipt)."""
    target = Path(path)
    m = Messages(ros_version or ros_version_of(target))
    points = [
        m.new(
            POINT,
            positions=traj.q[i].astype(np.float64),
            velocities=traj.qd[i].astype(np.float64),
            accelerations=traj.qdd[i].astype(np.float64),
            effort=np.zeros(0, np.float64),
            time_from_start=m.duration(float(traj.t[i])),
        )
        for i in range(len(traj.t))
    ]
    msg = m.new(
        TRAJECTORY,
        header=m.header(topic, stamp_ns),
        joint_names=list(traj.joint_names),
        points=points,
    )
    log_time = stamp_ns if stamp_ns > 0 else time.time_ns()
    message = BagMessage(topic, TRAJECTORY, log_time, msg)
    return write_bag(target, [message], m, storage=storage, error=ExecutionError)


def write_joint_state_bag(
    joint_log: JointStates,
    path: str | Path,
    *,
    ros_version: int | None = None,
    storage: str = "sqlite3",
    topic: str = JOINT_STATES_TOPIC,
) -> Path:
    """Write ``joint_log`` as JointState messages (stamps ``start_ns + t``) into a new bag."""
    target = Path(path)
    m = Messages(ros_version or ros_version_of(target))
    messages = joint_state_messages(joint_log, m, topic)
    return write_bag(target, messages, m, storage=storage, error=ExecutionError)


def _open(path: Path) -> Any:
    if not path.exists():
        raise ExecutionError(f"{path}: no such bag (a ROS1 .bag, a ROS2 folder or a .mcap file)")
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as err:
        raise ExecutionError(f"{path}: cannot open as a bag ({type(err).__name__}: {err})") from err
    return reader


def _connections(reader: Any, path: Path, msgtype: str, topic: str | None) -> list[Any]:
    conns = [c for c in reader.connections if c.msgtype == msgtype]
    topics = sorted({c.topic for c in conns})
    if topic is not None:
        conns = [c for c in conns if c.topic == topic]
        if not conns:
            raise ExecutionError(f"{path}: no {msgtype} on {topic}; {msgtype} topics: {topics}")
    elif len(topics) != 1:
        raise ExecutionError(
            f"{path}: {'no' if not topics else 'several'} {msgtype} topics {topics}; "
            + ("record one" if not topics else "name one")
        )
    return conns


def read_joint_state_bag(path: str | Path, topic: str | None = None) -> JointStates:
    """Joint positions (and velocities when every message has them) of a JointState topic,
    by header stamp (the log time where a stamp is zero): :func:`gaide_core.ros.joint_states_from`.
    Joint order: the first message's; messages missing some of its joints are skipped with a
    warning. ExecutionError unless at least two messages are usable."""
    source = Path(path)
    reader = _open(source)
    try:
        conns = _connections(reader, source, JOINT_STATE, topic)
        states, skipped = joint_states_from(_stamped(reader, conns), ExecutionError)
    except (SerdeError, TypesysError, ValueError, KeyError) as err:
        raise ExecutionError(f"{source}: cannot decode JointState messages ({err})") from err
    finally:
        reader.close()
    if skipped:
        names = None if states is None else states.names
        log.warning("%s: skipped %d JointState messages lacking joints %s", source, skipped, names)
    if states is None:
        raise ExecutionError(f"{source}: no usable JointState messages")
    return check_log(states, str(source))


def _stamped(reader: Any, conns: list[Any]) -> Iterator[tuple[int, Any]]:
    """(stamp ns, message) of every message on ``conns``, in log order."""
    for conn, log_time, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        yield message_stamp_ns(msg, int(log_time)), msg


def read_trajectory_bag(path: str | Path, topic: str | None = None) -> TimedTrajectory:
    """The first JointTrajectory message of a bag, as a trajectory (no jerk, no path)."""
    source = Path(path)
    reader = _open(source)
    try:
        conns = _connections(reader, source, TRAJECTORY, topic)
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            break
        else:
            raise ExecutionError(f"{source}: the JointTrajectory topic has no message")
    except (SerdeError, TypesysError, ValueError, KeyError) as err:
        raise ExecutionError(f"{source}: cannot decode the JointTrajectory ({err})") from err
    finally:
        reader.close()
    pts = msg.points
    if len(pts) < 2:
        raise ExecutionError(f"{source}: the trajectory has fewer than 2 points")
    t = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in pts])
    step = float(np.median(np.diff(t)))
    return TimedTrajectory(
        t=t,
        q=np.array([p.positions for p in pts], float),
        qd=np.array([p.velocities for p in pts], float),
        qdd=np.array([p.accelerations for p in pts], float),
        joint_names=tuple(str(n) for n in msg.joint_names),
        rate_hz=1.0 / step if step > 0 else 1.0,
    )
