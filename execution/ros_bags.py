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
storage, so ROS tools decode them without this project. Writers write to the path given as is;
callers that need an all-or-nothing write stage the path (``execution.staging``).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag1 import WriterError as Writer1Error
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.rosbag2 import WriterError as Writer2Error
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, TypesysError, get_typestore

from execution.joint_log import JointLog
from execution.trajectory import TimedTrajectory
from gaide_core.errors import ExecutionError
from gaide_core.types import Array

log = logging.getLogger(__name__)

TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
POINT = "trajectory_msgs/msg/JointTrajectoryPoint"
JOINT_STATE = "sensor_msgs/msg/JointState"
TRAJECTORY_TOPIC = "/joint_trajectory"
JOINT_STATES_TOPIC = "/joint_states"
STORAGES = ("sqlite3", "mcap")


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


def _writer_errors() -> tuple[type[BaseException], ...]:
    return (Writer1Error, Writer2Error, SerdeError, TypesysError, OSError, ValueError, TypeError)


class _Messages:
    """Message objects of one ROS version's typestore."""

    def __init__(self, ros_version: int) -> None:
        self.ros_version = ros_version
        self.store = get_typestore(Stores.ROS1_NOETIC if ros_version == 1 else Stores.ROS2_HUMBLE)
        self._seq = 0

    def new(self, msgtype: str, **fields: Any) -> Any:
        return self.store.types[msgtype](**fields)

    def header(self, stamp_ns: int, frame_id: str = "") -> Any:
        stamp = self.new(
            "builtin_interfaces/msg/Time", sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9
        )
        if self.ros_version == 2:
            return self.new("std_msgs/msg/Header", stamp=stamp, frame_id=frame_id)
        self._seq += 1
        return self.new("std_msgs/msg/Header", seq=self._seq - 1, stamp=stamp, frame_id=frame_id)

    def duration(self, seconds: float) -> Any:
        ns = round(seconds * 1e9)
        return self.new("builtin_interfaces/msg/Duration", sec=ns // 10**9, nanosec=ns % 10**9)

    def serialize(self, msg: Any, msgtype: str) -> bytes | memoryview:
        if self.ros_version == 1:
            return self.store.serialize_ros1(msg, msgtype)
        return self.store.serialize_cdr(msg, msgtype)


def _write(
    path: Path, topic: str, msgtype: str, stamped: list[tuple[int, Any]], b: _Messages, storage: str
) -> None:
    """Write messages (log time ns, message) on one topic into a new bag at ``path``."""
    if storage not in STORAGES:
        raise ExecutionError(f"storage must be one of {list(STORAGES)}, got {storage!r}")
    try:
        if b.ros_version == 1:
            with Writer1(path) as w1:
                conn = w1.add_connection(topic, msgtype, typestore=b.store)
                for stamp, msg in stamped:
                    w1.write(conn, stamp, b.serialize(msg, msgtype))
            return
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        with Writer2(path, version=Writer2.VERSION_LATEST, storage_plugin=plugin) as w2:
            conn = w2.add_connection(topic, msgtype, typestore=b.store)
            for stamp, msg in stamped:
                w2.write(conn, stamp, b.serialize(msg, msgtype))
    except _writer_errors() as err:
        raise ExecutionError(
            f"{path}: writing the bag failed ({type(err).__name__}: {err})"
        ) from err


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
    version = ros_version or ros_version_of(target)
    b = _Messages(version)
    points = [
        b.new(
            POINT,
            positions=traj.q[i].astype(np.float64),
            velocities=traj.qd[i].astype(np.float64),
            accelerations=traj.qdd[i].astype(np.float64),
            effort=np.zeros(0, np.float64),
            time_from_start=b.duration(float(traj.t[i])),
        )
        for i in range(len(traj.t))
    ]
    msg = b.new(
        TRAJECTORY,
        header=b.header(stamp_ns),
        joint_names=list(traj.joint_names),
        points=points,
    )
    log_time = stamp_ns if stamp_ns > 0 else time.time_ns()
    _write(target, topic, TRAJECTORY, [(log_time, msg)], b, storage)
    return target


def write_joint_state_bag(
    joint_log: JointLog,
    path: str | Path,
    *,
    ros_version: int | None = None,
    storage: str = "sqlite3",
    topic: str = JOINT_STATES_TOPIC,
) -> Path:
    """Write ``joint_log`` as JointState messages (stamps ``start_ns + t``) into a new bag."""
    target = Path(path)
    b = _Messages(ros_version or ros_version_of(target))
    empty = np.zeros(0, np.float64)
    stamped = []
    for i, t in enumerate(joint_log.t.tolist()):
        stamp = joint_log.start_ns + round(t * 1e9)
        msg = b.new(
            JOINT_STATE,
            header=b.header(stamp),
            name=list(joint_log.names),
            position=joint_log.q[i].astype(np.float64),
            velocity=empty if joint_log.qd is None else joint_log.qd[i].astype(np.float64),
            effort=empty,
        )
        stamped.append((stamp, msg))
    _write(target, topic, JOINT_STATE, stamped, b, storage)
    return target


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


def read_joint_state_bag(path: str | Path, topic: str | None = None) -> JointLog:
    """Joint positions (and velocities when every message has them) of a JointState topic,
    by header stamp (the log time where a stamp is zero). Joint order: the first message's;
    messages missing some of its joints are skipped with a warning."""
    source = Path(path)
    reader = _open(source)
    rows: list[tuple[int, Array, Array | None]] = []
    names: tuple[str, ...] | None = None
    skipped = 0
    try:
        for conn, log_time, raw in reader.messages(
            connections=_connections(reader, source, JOINT_STATE, topic)
        ):
            msg = reader.deserialize(raw, conn.msgtype)
            msg_names = [str(n) for n in msg.name]
            if names is None:
                names = tuple(msg_names)
            if not set(names) <= set(msg_names) or len(msg.position) != len(msg_names):
                skipped += 1
                continue
            idx = [msg_names.index(n) for n in names]
            position = np.asarray(msg.position, float)[idx]
            velocity = (
                np.asarray(msg.velocity, float)[idx]
                if len(msg.velocity) == len(msg_names)
                else None
            )
            stamp = int(msg.header.stamp.sec) * 10**9 + int(msg.header.stamp.nanosec)
            rows.append((stamp or int(log_time), position, velocity))
    except (SerdeError, TypesysError, ValueError, KeyError) as err:
        raise ExecutionError(f"{source}: cannot decode JointState messages ({err})") from err
    finally:
        reader.close()
    if skipped:
        log.warning("%s: skipped %d JointState messages lacking joints %s", source, skipped, names)
    if names is None or len(rows) < 2:
        raise ExecutionError(f"{source}: fewer than 2 usable JointState messages")
    rows.sort(key=lambda r: r[0])
    stamps = np.array([r[0] for r in rows], np.int64)
    keep = np.r_[True, np.diff(stamps) > 0]
    start = int(stamps[0])
    has_vel = all(r[2] is not None for r in rows)
    return JointLog(
        names=names,
        t=(stamps[keep] - start).astype(np.float64) * 1e-9,
        q=np.array([r[1] for r in rows])[keep],
        qd=np.array([r[2] for r in rows])[keep] if has_vel else None,
        start_ns=start,
    )


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
