"""Write ``Frames`` as a RealSense bag that ``read_bag`` (and ROS tools) read back.

Layouts (``perception.bag_layout`` lists the topics):

- ``BagLayout.SDK``: the librealsense recorder's topics under ``/device_0`` (depth on
  ``sensor_0/Depth_0``, color on ``sensor_1/Color_0``), StreamInfo and CameraInfo, the
  ``Depth Units`` option and the ``tf/0`` extrinsics with depth as reference stream; ROS1, or
  ROS2 as the rosbags conversion of such a bag holds it.
- ``BagLayout.ROS_WRAPPER``: realsense-ros topics under ``/camera`` (or ``namespace``), 16UC1
  millimetre depth, a CameraInfo beside every image, the extrinsics on ``/tf_static``.

Both add ``/joint_states`` (sensor_msgs/JointState, :func:`gaide_core.ros.joint_state_messages`)
when ``frames.joint_states`` is set. Every message's log time is its stamp; static messages are
logged at the first stamp. ROS1 bags carry full message definitions and md5 sums (as rosbag
record writes them), ROS2 bags carry the type definitions in their storage (sqlite3 schema,
mcap schema records), so other tools can decode them without this project.

The bag is written by :func:`gaide_core.ros.write_bag`, the one bag writer of the project:
into a temporary sibling and renamed into place, so on any error nothing is left at ``path``.
"""

from __future__ import annotations

import logging
import math
import re
from pathlib import Path

import numpy as np

from gaide_core import ros
from gaide_core.errors import BagError
from gaide_core.joints import JointStates
from gaide_core.ros import COMPRESSIONS, STORAGES, BagMessage
from gaide_core.transforms import is_rigid
from perception.bag_builder import STREAM_INFO, UINT32, MessageBuilder
from perception.bag_layout import (
    CAMERA_INFO,
    FLOAT32,
    IMAGE,
    TF_MESSAGE,
    TF_STATIC,
    TRANSFORM,
    WRAPPER_DEPTH_UNITS,
)
from perception.bag_tf import wrapper_tf_tree
from perception.frames import BagLayout, Frames, ImageStream

logger = logging.getLogger(__name__)

SDK_DEVICE = "/device_0"
SDK_STREAMS = {"depth": "/device_0/sensor_0/Depth_0", "color": "/device_0/sensor_1/Color_0"}
SDK_DEPTH_UNITS = "/device_0/sensor_0/option/Depth Units/value"
SDK_FILE_VERSION = 3  # librealsense's rosbag file format version
WRAPPER_NAMESPACE = "/camera"
_ROS_NAMESPACE = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)+$")
JOINT_STATES_TOPIC = "/joint_states"
_MAX_ROS_TIME_NS = 2**32 * 1_000_000_000  # ROS1 time is uint32 seconds


def write_bag(
    path: str | Path,
    frames: Frames,
    *,
    layout: BagLayout,
    ros_version: int = 1,
    storage: str = "sqlite3",
    namespace: str | None = None,
    aligned_depth: bool = False,
    compression: str = "lz4",
    chunk_bytes: int | None = None,
) -> Path:
    """Write ``frames`` as a bag in ``layout``.

    Args:
        path: ROS1: a new ``.bag`` file; ROS2: a new bag folder (no ``.bag`` suffix).
        frames: what to write; depth images (H, W) uint16 in ``depth_units`` m per unit, color
            (H, W, 3) uint8 RGB, stamps in ns, ``T_color_depth`` the depth optical frame in the
            color optical frame.
        layout: ``BagLayout.SDK`` or ``BagLayout.ROS_WRAPPER``.
        ros_version: 1 (rosbag v2.0 file) or 2 (rosbag2 folder).
        storage: ROS2 storage, ``"sqlite3"`` or ``"mcap"``.
        namespace: realsense-ros topic prefix (default ``/camera``); not used by the SDK layout.
        aligned_depth: realsense-ros only: write depth as ``aligned_depth_to_color`` (depth in
            the color camera's pixels: same intrinsics as color, ``T_color_depth`` identity).
        compression: ROS1 only: chunk compression, ``"lz4"`` (as the RealSense SDK writes),
            ``"bz2"`` or ``"none"``.
        chunk_bytes: ROS1 only: a chunk is closed once it holds more than this many
            uncompressed bytes (1 puts each message in a chunk of its own); None for rosbags'
            default (1 MiB).

    Returns:
        The path written.

    Raises:
        BagError: invalid arguments or frames (the message says what would be valid), an
            existing ``path``, or a failure while writing (then nothing is left at ``path``).
    """
    path = Path(path)
    _check_arguments(path, layout, ros_version, storage, namespace, aligned_depth)
    _check_chunks(ros_version, compression, chunk_bytes)
    _check_frames(frames)
    builder = MessageBuilder(ros_version)
    if layout is BagLayout.SDK:
        messages = _sdk_messages(frames, builder)
    else:
        ns = namespace or WRAPPER_NAMESPACE
        messages = _wrapper_messages(frames, builder, ns, aligned_depth)
    messages.extend(_joint_messages(frames.joint_states, builder))
    messages.sort(key=lambda m: m.stamp_ns)  # stable: same stamps keep the order made in
    ros.write_bag(
        path,
        messages,
        builder,
        storage=storage,
        compression=compression,
        chunk_bytes=chunk_bytes,
        replace=False,
        error=BagError,
    )
    logger.info(
        "wrote %s (%s layout, ROS%d%s): %d messages",
        path,
        layout.value,
        ros_version,
        f" {storage}" if ros_version == 2 else "",
        len(messages),
    )
    return path


def _check_arguments(
    path: Path,
    layout: BagLayout,
    ros_version: int,
    storage: str,
    namespace: str | None,
    aligned_depth: bool,
) -> None:
    if not isinstance(layout, BagLayout):
        raise BagError(f"layout must be one of {[m.name for m in BagLayout]}, got {layout!r}")
    if ros_version not in (1, 2):
        raise BagError(f"ros_version must be 1 or 2, got {ros_version!r}")
    if storage not in STORAGES:
        raise BagError(f"storage must be one of {list(STORAGES)}, got {storage!r}")
    if ros_version == 1 and storage != "sqlite3":
        raise BagError(f"storage={storage!r} applies to ROS2 bags; ROS1 bags have one format")
    if ros_version == 1 and path.suffix != ".bag":
        raise BagError(f"{path}: a ROS1 bag must be a file ending in .bag")
    if ros_version == 2 and path.suffix == ".bag":
        raise BagError(f"{path}: a ROS2 bag is a folder; give a path without the .bag suffix")
    if path.exists() or path.is_symlink():
        raise BagError(f"{path} already exists; write_bag does not overwrite: remove it first")
    if layout is BagLayout.SDK and (namespace is not None or aligned_depth):
        raise BagError(
            "namespace and aligned_depth apply to the realsense-ros layout only; the SDK layout "
            f"always writes under {SDK_DEVICE} with unaligned depth"
        )
    if namespace is not None and not _ROS_NAMESPACE.match(namespace):
        raise BagError(
            f"namespace must be a ROS name such as '/camera' or '/camera/camera', got {namespace!r}"
        )


def _check_chunks(ros_version: int, compression: str, chunk_bytes: int | None) -> None:
    if compression not in COMPRESSIONS:
        raise BagError(f"compression must be one of {list(COMPRESSIONS)}, got {compression!r}")
    if chunk_bytes is not None and (
        isinstance(chunk_bytes, bool) or not isinstance(chunk_bytes, int) or chunk_bytes < 1
    ):
        raise BagError(
            f"chunk_bytes must be a positive number of bytes or None, got {chunk_bytes!r}"
        )
    if ros_version == 2 and (compression != "lz4" or chunk_bytes is not None):
        raise BagError(
            "compression and chunk_bytes apply to ROS1 bags only; a ROS2 bag's storage "
            "(sqlite3 or mcap) has no chunks to set"
        )


def _check_frames(frames: Frames) -> None:
    """Reject frames the bag could not represent, before anything is written."""
    if frames.depth is None and frames.color is None:
        raise BagError("frames hold neither a depth nor a color stream; nothing to write")
    for kind, stream in (("depth", frames.depth), ("color", frames.color)):
        if stream is None:
            continue
        if len(stream) == 0:
            raise BagError(f"the {kind} stream has no images; drop it (None) or add images")
        w, h = stream.intrinsics.width, stream.intrinsics.height
        shape, dtype = ((h, w), np.uint16) if kind == "depth" else ((h, w, 3), np.uint8)
        for i, image in enumerate(stream.images):
            if image.shape != shape or image.dtype != dtype:
                raise BagError(
                    f"{kind} image {i} is {image.dtype} {image.shape}; the {kind} stream "
                    f"({w}x{h} intrinsics) needs {np.dtype(dtype)} {shape}"
                )
        stamps = np.asarray(stream.stamps_ns)
        if stamps.size and (stamps.min() < 0 or stamps.max() >= _MAX_ROS_TIME_NS):
            raise BagError(f"{kind} stamps must be in [0, 2^32 s) as ROS time, got {stamps}")
    if frames.T_color_depth is not None and not is_rigid(frames.T_color_depth):
        raise BagError(f"T_color_depth must be a 4x4 rigid transform, got {frames.T_color_depth}")
    units = frames.depth_units
    if units is not None and not (math.isfinite(units) and units > 0):
        raise BagError(f"depth_units must be a positive number of metres, got {units}")
    js = frames.joint_states  # names, shapes and order: checked by JointStates itself
    if js is not None and (js.stamps_ns[0] < 0 or js.stamps_ns[-1] >= _MAX_ROS_TIME_NS):
        raise BagError(f"joint state stamps must be in [0, 2^32 s) as ROS time, got {js.stamps_ns}")


def _first_stamp(frames: Frames) -> int:
    """Earliest stamp (ns) of the frames and joint states: where static messages go."""
    stamps = [int(s.stamps_ns.min()) for s in (frames.depth, frames.color) if s is not None]
    if frames.joint_states is not None:
        stamps.append(int(frames.joint_states.stamps_ns[0]))
    return min(stamps)


def _fps(stream: ImageStream) -> int:
    """Nominal frame rate (Hz) from the median stamp spacing; 0 for a single frame."""
    if len(stream) < 2:
        return 0
    spacing = float(np.median(np.diff(np.sort(stream.stamps_ns))))
    return round(1e9 / spacing) if spacing > 0 else 0


def _sdk_messages(frames: Frames, b: MessageBuilder) -> list[BagMessage]:
    """Topics of the librealsense recorder (depth is the extrinsics reference stream 0)."""
    out: list[BagMessage] = []
    t0 = _first_stamp(frames)
    out.append(BagMessage("/file_version", UINT32, t0, b.new(UINT32, data=SDK_FILE_VERSION)))
    encodings = {"depth": "mono16", "color": "rgb8"}
    both = frames.depth is not None and frames.color is not None
    T = frames.T_color_depth
    poses = {"depth": np.eye(4), "color": T} if both and T is not None else None
    for kind, stream in (("depth", frames.depth), ("color", frames.color)):
        if stream is None:
            continue
        prefix = SDK_STREAMS[kind]
        info = b.new(STREAM_INFO, fps=_fps(stream), encoding=encodings[kind], is_recommended=False)
        out.append(BagMessage(f"{prefix}/info", STREAM_INFO, t0, info))
        topic = f"{prefix}/info/camera_info"
        info = b.camera_info(topic, 0, stream.frame_id, stream.intrinsics)
        out.append(BagMessage(topic, CAMERA_INFO, t0, info))
        if kind == "depth" and frames.depth_units is not None:
            units = b.new(FLOAT32, data=float(frames.depth_units))
            out.append(BagMessage(SDK_DEPTH_UNITS, FLOAT32, t0, units))
        if poses is not None:
            # tf/0: rs2 extrinsics from reference stream 0 (depth) to this stream, T_this_depth.
            out.append(BagMessage(f"{prefix}/tf/0", TRANSFORM, t0, b.transform(poses[kind])))
        topic = f"{prefix}/image/data"
        for stamp, image in zip(stream.stamps_ns.tolist(), stream.images, strict=True):
            msg = b.image(topic, stamp, stream.frame_id, image, encodings[kind])
            out.append(BagMessage(topic, IMAGE, stamp, msg))
    if frames.depth is not None and frames.depth_units is None:
        logger.warning("frames carry no depth units: the bag will need depth_units= to be read")
    return out


def _wrapper_messages(
    frames: Frames, b: MessageBuilder, namespace: str, aligned: bool
) -> list[BagMessage]:
    """Topics of realsense-ros: images with a CameraInfo each, extrinsics on /tf_static."""
    depth, color = frames.depth, frames.color
    if frames.depth_units is not None and not math.isclose(
        frames.depth_units, WRAPPER_DEPTH_UNITS, rel_tol=1e-6
    ):
        raise BagError(
            f"realsense-ros bags hold depth in millimetres (depth units {WRAPPER_DEPTH_UNITS} m); "
            f"these frames have {frames.depth_units} m per unit: rescale the depth images or "
            "write the SDK layout, which records the units"
        )
    base = namespace.rsplit("/", 1)[-1]
    color_frame = (color.frame_id if color else "") or f"{base}_color_optical_frame"
    depth_frame = (depth.frame_id if depth else "") or f"{base}_depth_optical_frame"
    T = frames.T_color_depth
    if aligned:
        _check_aligned(frames)
        depth_frame, T = color_frame, np.eye(4)
    elif depth is not None and color is not None and depth_frame == color_frame:
        raise BagError(
            f"depth and color share the frame id {depth_frame!r}; realsense-ros needs distinct "
            "optical frames (or aligned_depth=True for depth aligned to color)"
        )
    out: list[BagMessage] = []
    if depth is not None and color is not None and T is not None:
        tree = wrapper_tf_tree(
            T,
            f"{base}_depth_optical_frame" if aligned else depth_frame,
            color_frame,
            f"{base}_link",
        )
        t0 = _first_stamp(frames)
        transforms = [
            b.new(
                "geometry_msgs/msg/TransformStamped",
                header=b.header(TF_STATIC, t0, parent),
                child_frame_id=child,
                transform=b.transform(T_parent_child),
            )
            for parent, child, T_parent_child in tree
        ]
        tf = b.new(TF_MESSAGE, transforms=transforms)
        out.append(BagMessage(TF_STATIC, TF_MESSAGE, t0, tf, latching=True))
    streams = (
        ("depth", depth, "aligned_depth_to_color" if aligned else "depth", depth_frame, "16UC1"),
        ("color", color, "color", color_frame, "rgb8"),
    )
    for _kind, stream, sub, frame_id, encoding in streams:
        if stream is None:
            continue
        image_topic = f"{namespace}/{sub}/{'image_raw' if sub != 'depth' else 'image_rect_raw'}"
        info_topic = f"{namespace}/{sub}/camera_info"
        for stamp, image in zip(stream.stamps_ns.tolist(), stream.images, strict=True):
            msg = b.image(image_topic, stamp, frame_id, image, encoding)
            out.append(BagMessage(image_topic, IMAGE, stamp, msg))
            info = b.camera_info(info_topic, stamp, frame_id, stream.intrinsics)
            out.append(BagMessage(info_topic, CAMERA_INFO, stamp, info))
    return out


def _check_aligned(frames: Frames) -> None:
    depth, color = frames.depth, frames.color
    if depth is None or color is None:
        raise BagError("aligned_depth=True needs both a depth and a color stream")
    same_pixels = (
        depth.intrinsics.width == color.intrinsics.width
        and depth.intrinsics.height == color.intrinsics.height
        and np.allclose(depth.intrinsics.K, color.intrinsics.K)
    )
    if not same_pixels:
        raise BagError(
            "aligned depth is in the color camera's pixels: the depth intrinsics must equal the "
            f"color intrinsics (depth K {depth.intrinsics.K.tolist()}, {depth.intrinsics.width}x"
            f"{depth.intrinsics.height}; color K {color.intrinsics.K.tolist()}, "
            f"{color.intrinsics.width}x{color.intrinsics.height})"
        )
    if frames.T_color_depth is not None and not np.allclose(
        frames.T_color_depth, np.eye(4), atol=1e-9
    ):
        raise BagError("aligned depth has T_color_depth = identity; these frames carry another")


def _joint_messages(js: JointStates | None, b: MessageBuilder) -> list[BagMessage]:
    """JointState messages on /joint_states (positions in rad, velocities in rad/s when the
    series has them; no effort)."""
    return [] if js is None else ros.joint_state_messages(js, b, JOINT_STATES_TOPIC)
