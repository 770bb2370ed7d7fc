"""ROS messages and bags (with rosbags; no ROS installation), for every package that writes or
reads them.

perception writes RealSense bags (the synthetic recorder) and reads the joint states in them;
execution writes trajectories and joint-state logs for controllers and reads logs back. Both
make messages in a rosbags typestore of one ROS version, stamp them and write them the same
way, so that part is here once:

- :class:`Messages`: message objects of ROS1 (noetic) or ROS2 (humble): ``Time``,
  ``Duration``, ``Header`` (ROS1 headers count ``seq`` per topic), ``JointState``, any other
  type by name, and their wire bytes;
- :func:`stamp_ns` and :func:`message_stamp_ns`: the time of a message read back;
- :func:`joint_state_messages` and :func:`joint_states_from`: a
  :class:`~gaide_core.joints.JointStates` series as ``sensor_msgs/JointState`` messages, and
  back;
- :class:`BagMessage` and :func:`write_bag`: messages into a new ROS1 ``.bag`` file or ROS2
  bag folder (``sqlite3`` or ``mcap`` storage), staged and renamed into place.

ROS1 bags carry full message definitions and md5 sums (as ``rosbag record`` writes them), ROS2
bags carry the type definitions in their storage (sqlite3 schema, mcap schema records), so
other tools decode them without this project.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag1 import WriterError as Writer1Error
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.rosbag2 import WriterError as Writer2Error
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

from gaide_core.atomic import staged_outputs
from gaide_core.errors import GaideError
from gaide_core.joints import JointStates
from gaide_core.types import FloatArray

__all__ = [
    "COMPRESSIONS",
    "JOINT_STATE",
    "STORAGES",
    "BagMessage",
    "Messages",
    "joint_state_messages",
    "joint_states_from",
    "message_stamp_ns",
    "stamp_ns",
    "write_bag",
]

JOINT_STATE = "sensor_msgs/msg/JointState"
STORAGES = ("sqlite3", "mcap")  # ROS2 storage plugins
COMPRESSIONS = ("lz4", "bz2", "none")  # ROS1 chunk compression


class Messages:
    """Makes message objects of one ROS version's typestore, with ``extra_types`` (name ->
    ``.msg`` text) registered where the stock store lacks them."""

    def __init__(self, ros_version: int, extra_types: Mapping[str, str] | None = None) -> None:
        self.ros_version = ros_version
        self.typestore = get_typestore(
            Stores.ROS1_NOETIC if ros_version == 1 else Stores.ROS2_HUMBLE
        )
        extra: dict[str, Any] = {}
        for name, text in (extra_types or {}).items():
            if name not in self.typestore.fielddefs:
                extra.update(get_types_from_msg(text, name))
        self.typestore.register(extra)
        self._seq: dict[str, int] = {}

    def new(self, msgtype: str, **fields: Any) -> Any:
        return self.typestore.types[msgtype](**fields)

    def time(self, stamp_ns: int) -> Any:
        return self.new(
            "builtin_interfaces/msg/Time", sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9
        )

    def duration(self, seconds: float) -> Any:
        ns = round(seconds * 1e9)
        return self.new("builtin_interfaces/msg/Duration", sec=ns // 10**9, nanosec=ns % 10**9)

    def header(self, topic: str, stamp_ns: int, frame_id: str = "") -> Any:
        """A header stamped ``stamp_ns``; in ROS1 its ``seq`` counts the topic's headers."""
        if self.ros_version == 2:
            return self.new("std_msgs/msg/Header", stamp=self.time(stamp_ns), frame_id=frame_id)
        seq = self._seq.get(topic, 0)
        self._seq[topic] = seq + 1
        return self.new(
            "std_msgs/msg/Header", seq=seq, stamp=self.time(stamp_ns), frame_id=frame_id
        )

    def joint_state(
        self,
        topic: str,
        stamp_ns: int,
        names: Sequence[str],
        position: FloatArray,
        velocity: FloatArray | None = None,
    ) -> Any:
        """A JointState (rad, rad/s; no velocity when None, never an effort)."""
        empty = np.zeros(0, dtype=np.float64)
        return self.new(
            JOINT_STATE,
            header=self.header(topic, stamp_ns),
            name=list(names),
            position=np.asarray(position, dtype=np.float64),
            velocity=empty if velocity is None else np.asarray(velocity, dtype=np.float64),
            effort=empty,
        )

    def serialize(self, msg: Any, msgtype: str) -> bytes | memoryview:
        """Wire bytes of ``msg``: ROS1 serialization, or CDR (little-endian) for ROS2."""
        if self.ros_version == 1:
            return self.typestore.serialize_ros1(msg, msgtype)
        return self.typestore.serialize_cdr(msg, msgtype)


def stamp_ns(stamp: Any) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/Time`` (``sec``, ``nanosec``)."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def message_stamp_ns(msg: Any, log_time_ns: int) -> int:
    """Stamp (ns) of a message with a header: ``header.stamp``, or the bag's log time when
    the header stamp is zero (drivers that leave it unset)."""
    stamp = stamp_ns(msg.header.stamp)
    return stamp if stamp != 0 else log_time_ns


@dataclass(frozen=True)
class BagMessage:
    """One message to write, logged at ``stamp_ns``; a latching topic (``/tf_static``) is
    marked so in a ROS1 bag."""

    topic: str
    msgtype: str
    stamp_ns: int
    msg: Any
    latching: bool = False


def joint_state_messages(
    states: JointStates, messages: Messages, topic: str = "/joint_states"
) -> list[BagMessage]:
    """One JointState per sample on ``topic``, header stamp and log time equal."""
    velocities = [None] * len(states.t) if states.qd is None else list(states.qd)
    return [
        BagMessage(
            topic,
            JOINT_STATE,
            stamp,
            messages.joint_state(topic, stamp, states.names, position, velocity),
        )
        for stamp, position, velocity in zip(
            states.stamps_ns.tolist(), states.q, velocities, strict=True
        )
    ]


def joint_states_from(
    stamped: Iterable[tuple[int, Any]], error: type[GaideError] = GaideError
) -> tuple[JointStates | None, int]:
    """JointState messages (stamp ns, message) as one series sorted by stamp, and how many
    messages were skipped. Joint order: the first message's (that names joints); messages
    lacking one of its joints (a gripper's on the same topic) or with fewer positions than
    names are skipped; velocities are kept when every message has them; of messages with
    the same stamp the first is kept. None when no message is usable; ``error`` from the
    series' checks (joint names that repeat)."""
    names: tuple[str, ...] | None = None
    rows: list[tuple[int, FloatArray, FloatArray | None]] = []
    skipped = 0
    for stamp, msg in stamped:
        msg_names = [str(n) for n in msg.name]
        if names is None and msg_names:
            names = tuple(msg_names)
        index = {n: i for i, n in enumerate(msg_names)}
        position = np.asarray(msg.position, dtype=np.float64)
        if names is None or len(position) != len(msg_names) or any(n not in index for n in names):
            skipped += 1
            continue
        idx = [index[n] for n in names]
        velocity = np.asarray(msg.velocity, dtype=np.float64)
        rows.append(
            (int(stamp), position[idx], velocity[idx] if len(velocity) == len(msg_names) else None)
        )
    if names is None or not rows:
        return None, skipped
    rows.sort(key=lambda r: r[0])
    stamps = np.array([r[0] for r in rows], dtype=np.int64)
    keep = np.flatnonzero(np.r_[True, np.diff(stamps) > 0])
    q = np.array([rows[i][1] for i in keep], dtype=np.float64).reshape(len(keep), len(names))
    has_velocity = all(r[2] is not None for r in rows)
    qd = np.array([rows[i][2] for i in keep], dtype=np.float64) if has_velocity else None
    return JointStates.from_stamps(names, stamps[keep], q, qd, error), skipped


def write_bag(
    path: str | os.PathLike[str],
    messages: Iterable[BagMessage],
    made_by: Messages,
    *,
    storage: str = "sqlite3",
    compression: str = "none",
    chunk_bytes: int | None = None,
    replace: bool = True,
    error: type[GaideError] = GaideError,
) -> Path:
    """Write ``messages``, in their order, into a new bag at ``path``: a ROS1 ``.bag`` file
    or a ROS2 folder, as ``made_by`` (their typestore) says.

    ``storage``: the ROS2 storage, ``sqlite3`` or ``mcap``. ``compression`` (``lz4``,
    ``bz2``, ``none``) and ``chunk_bytes`` (a chunk is closed once it holds more
    uncompressed bytes; None: rosbags' 1 MiB): ROS1 chunks. The bag is written into a
    temporary sibling and renamed into place: on any failure ``error`` names the bag and the
    cause, and nothing is left at ``path``. An existing bag there is replaced whole, or kept
    with ``replace=False`` (then ``error``).
    """
    target = Path(path)
    if storage not in STORAGES:
        raise error(f"storage must be one of {list(STORAGES)}, got {storage!r}")
    if compression not in COMPRESSIONS:
        raise error(f"compression must be one of {list(COMPRESSIONS)}, got {compression!r}")
    with staged_outputs([target], error) as (staged,):
        try:
            _write(staged, messages, made_by, storage, compression, chunk_bytes)
        except (
            Writer1Error,
            Writer2Error,
            SerdeError,
            TypesysError,
            OSError,
            ValueError,
            TypeError,
            KeyError,  # a message type the typestore lacks
        ) as err:
            raise error(f"{target}: writing the bag failed ({type(err).__name__}: {err})") from err
        if not replace and (target.exists() or target.is_symlink()):
            raise error(f"{target} appeared while writing; not overwriting it")
    return target


def _write(
    path: Path,
    messages: Iterable[BagMessage],
    made_by: Messages,
    storage: str,
    compression: str,
    chunk_bytes: int | None,
) -> None:
    """The writer loop: a connection per topic (made at its first message), then bytes."""
    typestore = made_by.typestore
    connections: dict[str, Any] = {}
    if made_by.ros_version == 1:
        bag1 = Writer1(path)
        if compression != "none":
            bag1.set_compression(Writer1.CompressionFormat[compression.upper()])
        if chunk_bytes is not None:
            bag1.chunk_threshold = chunk_bytes
        with bag1 as writer1:
            for m in messages:
                if m.topic not in connections:
                    connections[m.topic] = writer1.add_connection(
                        m.topic, m.msgtype, typestore=typestore, latching=1 if m.latching else None
                    )
                writer1.write(
                    connections[m.topic], int(m.stamp_ns), made_by.serialize(m.msg, m.msgtype)
                )
        return
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer2(path, version=Writer2.VERSION_LATEST, storage_plugin=plugin) as writer2:
        for m in messages:
            if m.topic not in connections:
                connections[m.topic] = writer2.add_connection(
                    m.topic, m.msgtype, typestore=typestore
                )
            writer2.write(
                connections[m.topic], int(m.stamp_ns), made_by.serialize(m.msg, m.msgtype)
            )
