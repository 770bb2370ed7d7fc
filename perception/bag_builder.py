"""ROS message objects for the bag writer, in either ROS version's typestore.

``MessageBuilder`` is :class:`gaide_core.ros.Messages` (a rosbags typestore, ``ROS1_NOETIC``
or ``ROS2_HUMBLE``, headers, JointState, serialization) plus the types the stock stores lack,
and fills the camera fields each version spells differently (ROS1 CameraInfo has
``D``/``K``/``R``/``P``, ROS2 ``d``/``k``/``r``/``p``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gaide_core.camera import Intrinsics
from gaide_core.ros import Messages
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


class MessageBuilder(Messages):
    """Messages of one ROS version's typestore (:class:`gaide_core.ros.Messages`: headers,
    JointState, wire bytes) with the RealSense types registered, and the camera's messages."""

    def __init__(self, ros_version: int) -> None:
        super().__init__(ros_version, EXTRA_TYPES)

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
