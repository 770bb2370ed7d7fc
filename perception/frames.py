"""What a RealSense recording holds, independent of the bag layout it came from.

Frames: ``T_color_depth`` is the pose of the depth optical frame in the color optical frame
(``p_color = T_color_depth @ p_depth``), both in the ROS optical convention (x right, y down,
z forward). Stamps are integer nanoseconds; depth images are raw sensor units (uint16), to be
multiplied by ``depth_units`` (m per unit). Joint states recorded beside the images are a
:class:`gaide_core.joints.JointStates` series (``error=BagError``).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from gaide_core.camera import Intrinsics
from gaide_core.errors import BagError
from gaide_core.joints import JointStates
from gaide_core.types import Array


class BagLayout(enum.Enum):
    """Topic layouts the reader understands (and the synthetic recorder writes)."""

    SDK = "sdk"  # RealSense SDK / viewer: /device_0/sensor_*/...
    ROS_WRAPPER = "realsense-ros"  # realsense-ros: /camera/color/image_raw, ...


@dataclass(frozen=True)
class ImageStream:
    """N images of one stream with their stamps (ns)."""

    intrinsics: Intrinsics
    images: tuple[np.ndarray, ...]  # depth: (H, W) uint16; color: (H, W, 3) uint8 RGB
    stamps_ns: npt.NDArray[np.int64]  # (N,)
    frame_id: str = ""

    def __post_init__(self) -> None:
        if len(self.images) != len(self.stamps_ns):
            raise BagError(f"{len(self.images)} images but {len(self.stamps_ns)} stamps")

    def __len__(self) -> int:
        return len(self.images)


@dataclass(frozen=True)
class Frames:
    """Everything read from one bag (or made by the synthetic recorder)."""

    source: Path
    layout: BagLayout
    depth: ImageStream | None
    color: ImageStream | None
    depth_units: float | None  # m per depth unit; None if the bag does not say
    T_color_depth: Array | None  # (4, 4) depth frame in color frame; None if unknown
    joint_states: JointStates | None = None  # the bag's /joint_states (sensor_msgs/JointState)
