"""A calibration in the forms ROS tools take: a hand-eye YAML and a static TF publisher line.

- ``handeye_yaml``: the layout of easy_handeye2's calibration files, which MoveIt users load
  with its publisher (``calibration_type``, the frames, ``transform.translation/rotation``).
- ``static_transform_command``: a ``ros2 run tf2_ros static_transform_publisher`` line with
  the named arguments of ROS 2 Humble and later.

The published transform is the one that holds while the robot moves: ``T_base_cam`` from the
base frame for a fixed camera (fixed target or eye-to-hand), ``T_flange_cam`` from the flange
frame for a camera on the flange (eye-in-hand).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from calibration.result import CalibrationResult, Setup
from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import CalibrationError
from gaide_core.transforms import to_xyz_quat
from gaide_core.types import Array

#: The RealSense ROS driver's name for the color camera's optical frame.
DEFAULT_CAMERA_FRAME = "camera_color_optical_frame"


@dataclass(frozen=True)
class Frames:
    """TF frame names: the robot's base, its flange (end effector) and the camera."""

    base: str
    flange: str
    camera: str = DEFAULT_CAMERA_FRAME


def published(result: CalibrationResult, frames: Frames) -> tuple[str, str, Array]:
    """(parent frame, child frame, parent-to-child transform) a TF publisher should send."""
    if result.setup is Setup.EYE_IN_HAND:
        if result.T_flange_cam is None:
            raise CalibrationError("an eye-in-hand calibration without T_flange_cam")
        return frames.flange, frames.camera, result.T_flange_cam
    return frames.base, frames.camera, result.T_base_cam


def handeye_yaml(result: CalibrationResult, frames: Frames) -> str:
    """The calibration as an easy_handeye2-style YAML document (metres, quaternion xyzw)."""
    parent, child, T = published(result, frames)
    xyz, quat = to_xyz_quat(np.asarray(T, np.float64))
    kind = "eye_in_hand" if result.setup is Setup.EYE_IN_HAND else "eye_on_base"
    data = {
        "parameters": {
            "name": "gaide",
            "calibration_type": kind,
            "robot_base_frame": frames.base,
            "robot_effector_frame": frames.flange,
            "tracking_base_frame": child,
            "tracking_marker_frame": "calibration_target",
            "freehand_robot_movement": False,
        },
        "transform": {
            "translation": dict(zip("xyz", map(float, xyz), strict=True)),
            "rotation": dict(zip("xyzw", map(float, quat), strict=True)),
        },
        "parent_frame": parent,
    }
    return yaml.safe_dump(data, sort_keys=False)


def static_transform_command(result: CalibrationResult, frames: Frames) -> str:
    """One shell line that publishes the calibration on /tf_static (ROS 2)."""
    parent, child, T = published(result, frames)
    xyz, quat = to_xyz_quat(np.asarray(T, np.float64))
    values = " ".join(
        f"--{name} {value:.9g}"
        for name, value in zip(("x", "y", "z", "qx", "qy", "qz", "qw"), (*xyz, *quat), strict=True)
    )
    return (
        f"ros2 run tf2_ros static_transform_publisher {values} "
        f"--frame-id {parent} --child-frame-id {child}"
    )


def save_handeye_yaml(
    result: CalibrationResult, frames: Frames, path: str | os.PathLike[str]
) -> Path:
    """Write ``handeye_yaml`` atomically, with the static TF line as a comment."""
    text = f"# {static_transform_command(result, frames)}\n" + handeye_yaml(result, frames)
    return write_bytes_atomic(path, text.encode(), CalibrationError)
