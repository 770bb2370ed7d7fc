"""Read RealSense recordings (ROS1 .bag, ROS2 bag folders, bare .mcap) with ``rosbags``.

``read_bag`` opens any bag ``rosbags.highlevel.AnyReader`` opens, detects the topic layout
(``perception.bag_layout``), and returns ``Frames``: raw depth (uint16 sensor units) and RGB
color images with their intrinsics and stamps, the depth units (m per unit), the
depth-to-color extrinsics ``T_color_depth`` and any joint states. Every bad input raises
``BagError`` with a message naming the problem and what would be valid.

Stamps are the messages' ``header.stamp`` (ns), or the bag's log time where a driver left the
header stamp at zero; the time window selects on the same stamps that are returned.

Damaged ROS1 bags are read as far as they are intact (``perception.rosbag1_reader``): corrupt
chunks are skipped, a missing or cut-off index is rebuilt from the complete chunks. The loss is
logged as one warning; when what is left lacks something needed (a stream's frames, its
camera_info, the depth units, the extrinsics) the ``BagError`` says so and names the damage.
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from gaide_core.errors import BagError
from gaide_core.joints import JointStates
from gaide_core.ros import joint_states_from
from perception.bag_damage import BagDamage
from perception.bag_extrinsics import T_color_depth
from perception.bag_layout import (
    CAMERA_INFO,
    WRAPPER_DEPTH_UNITS,
    StreamTopics,
    TopicMap,
    detect_layout,
    image_topics,
)
from perception.bag_messages import decode_camera_info, decode_float32
from perception.bag_scan import STREAMS, Scan, library_errors, scan
from perception.frames import BagLayout, Frames, ImageStream
from perception.rosbag1_reader import RecoveringReader

logger = logging.getLogger(__name__)

BAG_SUFFIXES = (".bag", ".mcap", ".db3")
VALID_INPUT = "a ROS1 .bag file, a ROS2 bag folder (sqlite3 or mcap storage) or a .mcap file"


@functools.cache
def _default_typestore() -> Any:
    """Types for ROS2 bags that carry no message definitions (older sqlite3 bags)."""
    return get_typestore(Stores.ROS2_HUMBLE)


def read_bag(
    path: str | Path,
    *,
    streams: Sequence[str] = STREAMS,
    start_ns: int | None = None,
    end_ns: int | None = None,
    max_frames: int | None = None,
    depth_units: float | None = None,
    namespace: str | None = None,
    default_extrinsics: bool = False,
) -> Frames:
    """Read a RealSense recording.

    Args:
        path: a ROS1 ``.bag`` file, a ROS2 bag folder (sqlite3 or mcap) or a ``.mcap`` file.
        streams: which of ``"depth"``, ``"color"`` to read; each is required (a missing one
            is an error) and the others are returned as None.
        start_ns: first stamp (ns, inclusive) of the frames to read; None for the start.
        end_ns: last stamp (ns, inclusive) of the frames to read; None for the end.
        max_frames: at most this many frames per stream (the first ones in the window).
        depth_units: metres per depth unit; overrides the bag's value (SDK layout) or the
            realsense-ros millimetre convention. Required when the bag does not record them.
        namespace: camera topic prefix (``/device_0``, ``/camera``, ``/camera/camera``) when
            the bag holds several cameras.
        default_extrinsics: when the bag records no depth-to-color extrinsics, assume the
            RealSense SDK's default (identity) with a warning instead of refusing the bag.
            Off by default: the identity misplaces depth by the imagers' baseline (~15 mm).

    Returns:
        Frames with depth (H, W) uint16 and color (H, W, 3) uint8 RGB images, stamps in ns,
        depth units in m per unit, ``T_color_depth`` (depth optical frame in color optical
        frame; None if the bag records no extrinsics and only one stream is read) and joint
        states (all of them, not windowed, so that every frame has its nearest state).

    Raises:
        BagError: the path is missing or not a bag, a required stream, its camera_info, the
            depth units or (reading both streams) the extrinsics are missing (also when they
            were lost to damage: the message then says what was lost), or the window holds no
            frame.
    """
    path = Path(path)
    wanted = _check_arguments(streams, start_ns, end_ns, max_frames, depth_units)
    reader, damage = _open(path)
    try:
        topics = {name: info.msgtype for name, info in reader.topics.items()}
        layout = detect_layout(topics, namespace)
        for kind in wanted:
            if getattr(layout, kind) is None:
                raise BagError(
                    f"{path}: no {kind} stream in the {layout.layout.value} layout under "
                    f"{layout.namespace!r}; image topics in the bag: {image_topics(topics)}"
                )
        collected = scan(reader, path, layout, wanted, start_ns, end_ns, max_frames)
        frames = _assemble(
            path,
            topics,
            layout,
            wanted,
            collected,
            depth_units,
            (start_ns, end_ns),
            default_extrinsics=default_extrinsics,
        )
    except BagError as err:
        if damage is not None and damage.damaged:
            # What is left is not enough: one error that says why, no warning beside it.
            raise BagError(f"{err}; the bag is damaged: {damage.summary()}") from err
        raise
    finally:
        reader.close()
    if damage is not None and damage.damaged:
        logger.warning("%s: damaged bag, read what is intact: %s", path, damage.summary())
    logger.info(
        "read %s (%s layout): %d depth, %d color frames, %s joint states",
        path,
        layout.layout.value,
        len(frames.depth) if frames.depth else 0,
        len(frames.color) if frames.color else 0,
        len(frames.joint_states.stamps_ns) if frames.joint_states else 0,
    )
    return frames


def _check_arguments(
    streams: Sequence[str],
    start_ns: int | None,
    end_ns: int | None,
    max_frames: int | None,
    depth_units: float | None,
) -> tuple[str, ...]:
    if isinstance(streams, str):
        streams = (streams,)
    wanted = tuple(dict.fromkeys(streams))
    if not wanted or any(s not in STREAMS for s in wanted):
        raise BagError(f"streams must be a non-empty selection of {list(STREAMS)}, got {streams!r}")
    if start_ns is not None and end_ns is not None and start_ns > end_ns:
        raise BagError(f"empty time window: start_ns {start_ns} is after end_ns {end_ns}")
    if max_frames is not None and max_frames < 1:
        raise BagError(f"max_frames must be at least 1 (or None for all), got {max_frames}")
    if depth_units is not None and not (math.isfinite(depth_units) and depth_units > 0):
        raise BagError(f"depth_units must be a positive number of metres, got {depth_units}")
    return wanted


def _open(path: Path) -> tuple[Any, BagDamage | None]:
    """An open AnyReader on ``path`` and, for a ROS1 bag, the account of its damage; or
    BagError saying why it is not a bag."""
    if not path.exists():
        raise BagError(f"{path}: no such file or folder; expected {VALID_INPUT}")
    if path.is_file() and path.suffix not in BAG_SUFFIXES:
        raise BagError(
            f"{path}: not a bag (a {path.suffix or 'suffix-less'} file); expected {VALID_INPUT}"
        )
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise BagError(f"{path}: folder has no metadata.yaml, so it is not a ROS2 bag folder")
    damage = None
    try:
        reader = AnyReader([path], default_typestore=_default_typestore())
        if not reader.is2:
            # The ROS1 reader that skips corrupt chunks and rebuilds a missing index.
            recovering = RecoveringReader(path)
            reader.readers = [recovering]
            damage = recovering.damage
        reader.open()
    except library_errors() as err:
        raise BagError(
            f"{path}: cannot open as a bag ({type(err).__name__}: {err}); it is corrupt, "
            f"truncated or not a bag. Expected {VALID_INPUT}"
        ) from err
    return reader, damage


def _assemble(
    path: Path,
    topics: dict[str, str | None],
    layout: TopicMap,
    wanted: tuple[str, ...],
    got: Scan,
    depth_units: float | None,
    window: tuple[int | None, int | None],
    *,
    default_extrinsics: bool,
) -> Frames:
    start_ns, end_ns = window
    streams: dict[str, ImageStream | None] = {k: None for k in STREAMS}
    for kind in wanted:
        stream_topics: StreamTopics = getattr(layout, kind)
        if not got.all_stamps[kind]:
            raise BagError(f"{path}: the {kind} topic {stream_topics.image} has no messages")
        if not got.images[kind]:
            first, last = min(got.all_stamps[kind]), max(got.all_stamps[kind])
            raise BagError(
                f"{path}: no {kind} frame in the time window [{start_ns}, {end_ns}] ns; the "
                f"bag's {kind} frames are stamped {first} to {last} ns"
            )
        streams[kind] = _image_stream(path, topics, layout, kind, got)
    units = _depth_units(path, layout, got, depth_units, required="depth" in wanted)
    return Frames(
        source=path,
        layout=layout.layout,
        depth=streams["depth"],
        color=streams["color"],
        depth_units=units,
        T_color_depth=T_color_depth(path, layout, wanted, got, default=default_extrinsics),
        joint_states=_joint_states(path, got),
    )


def _image_stream(
    path: Path, topics: dict[str, str | None], layout: TopicMap, kind: str, got: Scan
) -> ImageStream:
    stream_topics: StreamTopics = getattr(layout, kind)
    images = got.images[kind]
    sizes = {(im.shape[1], im.shape[0]) for im in images}
    if len(sizes) > 1:
        raise BagError(f"{path}: {stream_topics.image} images change size: {sorted(sizes)}")
    info_topic = stream_topics.camera_info
    if info_topic not in got.first and kind == "depth" and layout.aligned_depth:
        # Depth aligned to color is in the color camera's pixels.
        assert layout.color is not None  # aligned depth is only detected beside color
        info_topic = layout.color.camera_info
    if info_topic not in got.first:
        infos = sorted(n for n, t in topics.items() if t == CAMERA_INFO)
        raise BagError(
            f"{path}: no camera_info for the {kind} stream (expected a sensor_msgs/CameraInfo "
            f"on {stream_topics.camera_info}); camera_info topics in the bag: {infos or 'none'}"
        )
    info = got.first[info_topic]
    intrinsics = decode_camera_info(info, info_topic, sizes.pop())
    order = np.argsort(np.asarray(got.stamps[kind], dtype=np.int64), kind="stable")
    return ImageStream(
        intrinsics=intrinsics,
        images=tuple(images[i] for i in order),
        stamps_ns=np.asarray(got.stamps[kind], dtype=np.int64)[order],
        frame_id=got.frame_ids.get(kind) or str(info.header.frame_id),
    )


def _depth_units(
    path: Path, layout: TopicMap, got: Scan, override: float | None, *, required: bool
) -> float | None:
    """Metres per depth unit: the caller's value, else the bag's, else an error if needed."""
    recorded: float | None = None
    if layout.layout is BagLayout.ROS_WRAPPER:
        recorded = WRAPPER_DEPTH_UNITS
    elif layout.depth_units is not None and layout.depth_units in got.first:
        recorded = decode_float32(got.first[layout.depth_units].data)
        if not (math.isfinite(recorded) and recorded > 0):
            raise BagError(
                f"{path}: {layout.depth_units} records depth units {recorded}; they must be a "
                "positive number of metres (pass depth_units= to override)"
            )
    if override is not None:
        if recorded is not None and not math.isclose(override, recorded, rel_tol=1e-6):
            logger.warning(
                "%s: depth_units=%g overrides the bag's %g m per unit", path, override, recorded
            )
        return override
    if recorded is None and required:
        raise BagError(
            f"{path}: the bag records no depth units (no "
            f"'{layout.namespace}/sensor_<n>/option/Depth Units/value' topic); pass "
            "depth_units=<metres per unit> to read_bag. 0.001 (the RealSense default) would "
            "be assumed only if you pass it"
        )
    return recorded


def _joint_states(path: Path, got: Scan) -> JointStates | None:
    """Joint positions (rad) and velocities (rad/s, when every message has them) of the
    JointState topic, sorted by stamp (ns; of messages with the same stamp the first): see
    :func:`gaide_core.ros.joint_states_from`. None when no message is usable."""
    if not got.joints:
        return None
    states, skipped = joint_states_from(got.joints, BagError)
    if skipped:
        logger.warning(
            "%s: %d of %d JointState messages on %s lack some of the joints %s; skipped",
            path,
            skipped,
            len(got.joints),
            got.joint_topic,
            None if states is None else states.names,
        )
    return states
