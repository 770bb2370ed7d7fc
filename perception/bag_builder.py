"""ROS message objects for the bag writer, in either ROS version's typestore.

``MessageBuilder`` wraps a rosbags typestore (``ROS1_NOETIC`` or ``ROS2_HUMBLE``) plus the
types the stock stores lack, and fills the fields each version spells differently (ROS1
headers carry ``seq``; ROS1 CameraInfo has ``D``/``K``/``R``/``P``, ROS2 ``d``/``k``/``r``/``p``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from gaide_core.camera import Intrinsics
from gaide_core.transforms import to_xyz_quat
from gaide_core.types import Array
from perception.bag_layout import CAMERA_INFO, IMAGE, TF_MESSAGE, TRANSFORM

STREAM_INFO = "realsense_msgs/msg/StreamInfo"
UINT32 = "std_msgs/msg/UInt32"
# Definitions the stock typestores lack (realsense_msgs is librealsense's own package; noetic's
# store has no tf2_msgs). Text as in the packages' .msg files.
EXTRA_TYPES = {
    STREAM_INFO: "uint32 fps\nstring encoding\nbool is_recommended\n",
    TF_MESSAGE: "geometry_msgs/TransformStamped[] transforms\n",
}


@dataclass(order=True)
class Message:
    """One message to write: sorted by log time (ns), then by the order it was made in."""

    stamp_ns: int
    order: int
    topic: str = field(compare=False)
    msgtype: str = field(compare=False)
    msg: Any = field(compare=False)
    latching: bool = field(compare=False, default=False)


class MessageBuilder:
    """Makes message objects of one ROS version's typestore."""

    def __init__(self, ros_version: int) -> None:
        self.ros_version = ros_version
        self.typestore = get_typestore(
            Stores.ROS1_NOETIC if ros_version == 1 else Stores.ROS2_HUMBLE
        )
        extra: dict[str, Any] = {}
        for name, text in EXTRA_TYPES.items():
            if name not in self.typestore.fielddefs:
                extra.update(get_types_from_msg(text, name))
        self.typestore.register(extra)
        self._seq: dict[str, int] = {}

    def new(self, msgtype: str, **fields: Any) -> Any:
        return self.typestore.types[msgtype](**fields)

    def header(self, topic: str, stamp_ns: int, frame_id: str) -> Any:
        stamp = self.new(
            "builtin_interfaces/msg/Time", sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9
        )
        if self.ros_version == 2:
            return self.new("std_msgs/msg/Header", stamp=stamp, frame_id=frame_id)
        seq = self._seq.get(topic, 0)
        self._seq[topic] = seq + 1
        return self.new("std_msgs/msg/Header", seq=seq, stamp=stamp, frame_id=frame_id)

    def image(
        self, topic: str, stamp_ns: int, frame_id: str, image: np.ndarray, encoding: str
    ) -> Any:
        # Little-endian, unpadded rows: is_bigendian 0, step = width * bytes per pixel.
        data = np.ascontiguousarray(image, dtype=image.dtype.newbyteorder("<")).view(np.uint8)
        height, width = image.shape[:2]
        return self.new(
            IMAGE,
            header=self.header(topic, stamp_ns, frame_id),
            height=height,
            width=width,
            encoding=encoding,
            is_bigendian=0,
            step=data.size // height,
            data=data.reshape(-1),
        )

    def camera_info(self, topic: str, stamp_ns: int, frame_id: str, intr: Intrinsics) -> Any:
        P = np.hstack([intr.K, np.zeros((3, 1))])
        upper = self.ros_version == 1  # ROS1 spells the matrices D, K, R, P
        matrices = {"D": intr.D, "K": intr.K, "R": np.eye(3), "P": P}
        return self.new(
            CAMERA_INFO,
            header=self.header(topic, stamp_ns, frame_id),
            height=intr.height,
            width=intr.width,
            distortion_model=intr.distortion_model,
            **{
                (k if upper else k.lower()): np.asarray(v, dtype=np.float64).ravel()
                for k, v in matrices.items()
            },
            binning_x=0,
            binning_y=0,
            roi=self.new(
                "sensor_msgs/msg/RegionOfInterest",
                x_offset=0,
                y_offset=0,
                height=0,
                width=0,
                do_rectify=False,
            ),
        )

    def transform(self, T: Array) -> Any:
        xyz, quat = to_xyz_quat(T)
        return self.new(
            TRANSFORM,
            translation=self.new("geometry_msgs/msg/Vector3", x=xyz[0], y=xyz[1], z=xyz[2]),
            rotation=self.new(
                "geometry_msgs/msg/Quaternion", x=quat[0], y=quat[1], z=quat[2], w=quat[3]
            ),
        )


class MessageList:
    """Collects ``Message`` entries in creation order."""

    def __init__(self, start: int = 0) -> None:
        self.items: list[Message] = []
        self._start = start

    def add(
        self, stamp_ns: int, topic: str, msgtype: str, msg: Any, latching: bool = False
    ) -> None:
        order = self._start + len(self.items)
        self.items.append(Message(int(stamp_ns), order, topic, msgtype, msg, latching))


def serialize(typestore: Any, ros_version: int, msg: Any, msgtype: str) -> bytes | memoryview:
    """Wire bytes of ``msg``: ROS1 serialization or CDR (little-endian) for ROS2."""
    if ros_version == 1:
        return typestore.serialize_ros1(msg, msgtype)
    return typestore.serialize_cdr(msg, msgtype)
