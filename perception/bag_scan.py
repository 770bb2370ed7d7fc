"""One pass over a bag's messages: what ``read_bag`` needs, library errors translated.

Images are deserialized only while their stream still wants frames, decoded only inside the
time window; static messages (CameraInfo, options, extrinsics) are kept at their first
occurrence; /tf_static and joint states are kept whole.
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReaderError
from rosbags.rosbag1 import ReaderError as Reader1Error
from rosbags.rosbag2 import ReaderError as Reader2Error
from rosbags.serde import SerdeError
from rosbags.typesys import TypesysError

from gaide_core.errors import BagError
from gaide_core.ros import message_stamp_ns
from gaide_core.types import Array
from perception.bag_layout import TopicMap
from perception.bag_messages import decode_color, decode_depth, decode_transform

logger = logging.getLogger(__name__)

STREAMS = ("depth", "color")


def library_errors() -> tuple[type[BaseException], ...]:
    """What rosbags (and the formats under it) raise on a file that is not a sound bag."""
    return (
        AnyReaderError,
        Reader1Error,
        Reader2Error,
        SerdeError,
        TypesysError,
        struct.error,
        EOFError,
        OSError,
        ValueError,
        KeyError,
        IndexError,
        AssertionError,  # rosbags asserts on some malformed records
    )


@dataclass
class Scan:
    """What one pass over the bag's messages gathered (stamps in ns)."""

    images: dict[str, list[np.ndarray]] = field(default_factory=lambda: {k: [] for k in STREAMS})
    stamps: dict[str, list[int]] = field(default_factory=lambda: {k: [] for k in STREAMS})
    all_stamps: dict[str, list[int]] = field(default_factory=lambda: {k: [] for k in STREAMS})
    frame_ids: dict[str, str] = field(default_factory=dict)
    first: dict[str, Any] = field(default_factory=dict)  # topic -> first message
    tf_edges: list[tuple[str, str, Array]] = field(default_factory=list)
    joint_topic: str | None = None  # the JointState topic read
    joints: list[tuple[int, Any]] = field(default_factory=list)  # (stamp ns, JointState)


def _messages(reader: Any, path: Path, connections: list[Any]) -> Iterator[tuple[Any, int, Any]]:
    """(connection, log time ns, raw bytes) of ``connections``, library errors translated.

    Messages stay serialized until ``deserialize``: frames beyond ``max_frames`` cost nothing.
    """
    iterator = reader.messages(connections=connections)
    while True:
        try:
            conn, log_ns, raw = next(iterator)
        except StopIteration:
            return
        except library_errors() as err:
            raise BagError(
                f"{path}: the bag is truncated or corrupt ({type(err).__name__}: {err}); "
                "re-record or re-copy it"
            ) from err
        yield conn, log_ns, raw


def deserialize(reader: Any, path: Path, raw: bytes, conn: Any) -> Any:
    try:
        return reader.deserialize(raw, conn.msgtype)
    except library_errors() as err:
        raise BagError(
            f"{path}: a {conn.msgtype} message on {conn.topic} cannot be decoded "
            f"({type(err).__name__}: {err}); the bag is corrupt or its type definition is wrong"
        ) from err


def scan(
    reader: Any,
    path: Path,
    layout: TopicMap,
    wanted: tuple[str, ...],
    start_ns: int | None,
    end_ns: int | None,
    max_frames: int | None,
) -> Scan:
    """One pass over the needed topics: images in the window, first static messages, tf."""
    image_kind = {getattr(layout, k).image: k for k in wanted}
    static = {
        t
        for s in (layout.depth, layout.color)
        if s is not None
        for t in (s.camera_info, s.tf)
        if t is not None
    }
    static |= {t for t in (layout.depth_units, layout.extrinsics) if t is not None}
    joint_topic = _joint_topic(path, layout)
    needed = set(image_kind) | static | ({joint_topic} if joint_topic else set())
    if layout.tf_static:
        needed.add(layout.tf_static)
    connections = [c for c in reader.connections if c.topic in needed]
    decode: dict[str, Callable[[Any, str], np.ndarray]] = {
        "depth": decode_depth,
        "color": decode_color,
    }
    out = Scan(joint_topic=joint_topic)
    for conn, log_ns, raw in _messages(reader, path, connections):
        topic = conn.topic
        if topic in image_kind:
            kind = image_kind[topic]
            if max_frames is not None and len(out.images[kind]) >= max_frames:
                continue
            msg = deserialize(reader, path, raw, conn)
            stamp = message_stamp_ns(msg, log_ns)
            out.all_stamps[kind].append(stamp)
            if (start_ns is not None and stamp < start_ns) or (
                end_ns is not None and stamp > end_ns
            ):
                continue
            out.images[kind].append(decode[kind](msg, topic))
            out.stamps[kind].append(stamp)
            out.frame_ids.setdefault(kind, str(msg.header.frame_id))
        elif topic in static:
            if topic not in out.first and _registered(reader, conn):
                out.first[topic] = deserialize(reader, path, raw, conn)
        elif topic == layout.tf_static:
            msg = deserialize(reader, path, raw, conn)
            for tf in msg.transforms:
                T = decode_transform(tf.transform, topic)
                out.tf_edges.append((str(tf.header.frame_id), str(tf.child_frame_id), T))
        else:  # joint states
            msg = deserialize(reader, path, raw, conn)
            out.joints.append((message_stamp_ns(msg, log_ns), msg))
    return out


def _registered(reader: Any, conn: Any) -> bool:
    """Whether the bag's types can decode ``conn`` (realsense2_camera_msgs may be absent)."""
    known = conn.msgtype in reader.typestore.fielddefs
    if not known:
        logger.info("%s: type %s is not defined in the bag; ignored", conn.topic, conn.msgtype)
    return known


def _joint_topic(path: Path, layout: TopicMap) -> str | None:
    """The JointState topic to read: ``/joint_states`` if there are several."""
    topics = layout.joint_states
    if not topics:
        return None
    topic = "/joint_states" if "/joint_states" in topics else topics[0]
    if len(topics) > 1:
        logger.info("%s: several JointState topics %s; using %s", path, list(topics), topic)
    return topic
