"""Decoding of the ROS messages a RealSense bag holds into numpy arrays and frames types.

Messages are the objects ``rosbags`` deserializes; ROS1 and ROS2 spell some fields
differently (CameraInfo ``K``/``D`` in ROS1 definitions, ``k``/``d`` in ROS2), and both
spellings are accepted. Image decoding is vectorized: one reshape and one slice per image,
honouring ``step`` (row padding) and ``is_bigendian``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from gaide_core.camera import Intrinsics
from gaide_core.errors import BagError
from gaide_core.transforms import from_xyz_quat
from gaide_core.types import Array

DEPTH_ENCODINGS = ("16UC1", "mono16")
# color encoding -> (channels per pixel, channel indices giving R, G, B)
COLOR_ENCODINGS: dict[str, tuple[int, tuple[int, int, int]]] = {
    "rgb8": (3, (0, 1, 2)),
    "bgr8": (3, (2, 1, 0)),
    "rgba8": (4, (0, 1, 2)),
    "bgra8": (4, (2, 1, 0)),
    "mono8": (1, (0, 0, 0)),
}


def _field(msg: Any, *names: str) -> Any:
    """The first attribute of ``msg`` among ``names`` (ROS1/ROS2 spellings)."""
    for name in names:
        if hasattr(msg, name):
            return getattr(msg, name)
    raise BagError(f"{msg.__msgtype__} message has none of the fields {list(names)}")


def _pixel_rows(msg: Any, bytes_per_pixel: int, topic: str) -> npt.NDArray[np.uint8]:
    """The (H, W * bytes_per_pixel) bytes of an Image, row padding (``step``) dropped."""
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    row_bytes = width * bytes_per_pixel
    if height <= 0 or width <= 0:
        raise BagError(f"{topic}: image size must be positive, got {width}x{height}")
    if step < row_bytes:
        raise BagError(
            f"{topic}: step {step} B is less than width {width} x {bytes_per_pixel} B/pixel "
            f"({msg.encoding}); step must be at least {row_bytes}"
        )
    data = np.frombuffer(msg.data, dtype=np.uint8)
    needed = height * step
    if data.size < needed:
        raise BagError(
            f"{topic}: image data has {data.size} B, a {width}x{height} {msg.encoding} image "
            f"with step {step} needs {needed} B"
        )
    return data[: height * step].reshape(height, step)[:, :row_bytes]


def decode_depth(msg: Any, topic: str = "depth") -> npt.NDArray[np.uint16]:
    """Raw depth (H, W) uint16 (sensor units) of a ``16UC1``/``mono16`` Image."""
    if msg.encoding not in DEPTH_ENCODINGS:
        raise BagError(
            f"{topic}: depth encoding {msg.encoding!r} is not supported; "
            f"expected one of {list(DEPTH_ENCODINGS)}"
        )
    rows = np.ascontiguousarray(_pixel_rows(msg, 2, topic))
    dtype = np.dtype(">u2") if msg.is_bigendian else np.dtype("<u2")
    return rows.view(dtype).reshape(int(msg.height), int(msg.width)).astype(np.uint16)


def decode_color(msg: Any, topic: str = "color") -> npt.NDArray[np.uint8]:
    """RGB (H, W, 3) uint8 of an ``rgb8``/``bgr8``/``rgba8``/``bgra8``/``mono8`` Image."""
    if msg.encoding not in COLOR_ENCODINGS:
        raise BagError(
            f"{topic}: color encoding {msg.encoding!r} is not supported; "
            f"expected one of {list(COLOR_ENCODINGS)}"
        )
    channels, order = COLOR_ENCODINGS[msg.encoding]
    rows = _pixel_rows(msg, channels, topic)
    pixels = rows.reshape(int(msg.height), int(msg.width), channels)
    return np.ascontiguousarray(pixels[:, :, list(order)])


def decode_camera_info(
    msg: Any, topic: str, image_size: tuple[int, int] | None = None
) -> Intrinsics:
    """Intrinsics of a ``sensor_msgs/CameraInfo``.

    Args:
        msg: the deserialized CameraInfo (ROS1 ``K``/``D`` or ROS2 ``k``/``d`` fields).
        topic: its topic, for error messages.
        image_size: (width, height) of the stream's images (pixels), used when the
            CameraInfo leaves its size at zero and checked against it otherwise.
    """
    K = np.asarray(_field(msg, "K", "k"), dtype=np.float64).reshape(3, 3)
    D = np.asarray(_field(msg, "D", "d"), dtype=np.float64).ravel().copy()
    width, height = int(msg.width), int(msg.height)
    if image_size is not None:
        if width == 0 and height == 0:
            width, height = image_size
        elif (width, height) != image_size:
            raise BagError(
                f"{topic}: camera_info is {width}x{height} but the images are "
                f"{image_size[0]}x{image_size[1]}; they must match"
            )
    return Intrinsics.checked(
        width, height, K, D, str(msg.distortion_model), error=BagError, where=topic
    )


def decode_transform(msg: Any, topic: str) -> Array:
    """4x4 matrix of a ``geometry_msgs/Transform`` (translation in m, quaternion x, y, z, w)."""
    t, q = msg.translation, msg.rotation
    quat = np.array([q.x, q.y, q.z, q.w], dtype=np.float64)
    xyz = np.array([t.x, t.y, t.z], dtype=np.float64)
    norm = float(np.linalg.norm(quat))
    if not np.all(np.isfinite(quat)) or not np.all(np.isfinite(xyz)) or norm < 1e-6:
        raise BagError(
            f"{topic}: transform is not a finite rigid transform (translation {xyz}, "
            f"quaternion {quat}); the quaternion must be finite and non-zero"
        )
    return from_xyz_quat(xyz, quat / norm)


def decode_float32(value: float) -> float:
    """A float32 option value as the decimal it was written from (0.001, not 0.0010000000475).

    RealSense stores options as float32; the shortest decimal that round-trips through
    float32 is the value the device reported.
    """
    return float(str(np.float32(value)))
