"""Calibrate camera to base from a bag (fixed target, or hand-eye with the bag's joint states)
or from photos with an intrinsics file and a flange pose per photo."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import numpy.typing as npt

from calibration.detect import detect
from calibration.fixed import calibrate_fixed, load_target_pose
from calibration.hand_eye import calibrate_hand_eye
from calibration.overlay import draw_overlay
from calibration.pnp import solve_pose
from calibration.result import CalibrationResult, Setup
from calibration.targets import Target
from gaide_core.errors import BagError, CalibrationError
from gaide_core.types import Array
from perception.align import depth_in_color
from perception.bag_reader import read_bag
from perception.frames import Frames
from planning.robot_model import RobotModel


@dataclass(frozen=True)
class CalibrationRun:
    result: CalibrationResult
    overlay: npt.NDArray[np.uint8]  # RGB, the first used frame with corners and axes
    frames: Frames


def _depths(frames: Frames) -> list[Array] | None:
    if frames.depth is None or frames.depth_units is None or frames.color is None:
        return None
    return [depth_in_color(frames, i) for i in range(len(frames.color))]


def flange_poses(frames: Frames, robot: RobotModel, flange: str) -> list[Array]:
    """T_base_flange at each color frame, from the joint state nearest in time (FK)."""
    js = frames.joint_states
    if js is None or len(js.stamps_ns) == 0:
        raise CalibrationError(
            f"{frames.source}: hand-eye needs joint states (sensor_msgs/JointState) in the bag"
        )
    missing = [n for n in robot.joint_names if n not in js.names]
    if missing:
        raise CalibrationError(
            f"{frames.source}: joint states lack joints {missing}; they have {list(js.names)}"
        )
    order = [js.names.index(n) for n in robot.joint_names]
    assert frames.color is not None
    return [robot.frame_pose(js.at(int(s))[order], flange) for s in frames.color.stamps_ns]


def calibrate_bag(
    bag: str | Path,
    *,
    mode: str,
    robot: RobotModel | None = None,
    target: Target | None = None,
    target_pose: str | Path | None = None,
    flange: str | None = None,
    max_frames: int | None = None,
    setup: Setup | str = Setup.EYE_TO_HAND,
) -> CalibrationRun:
    """Calibrate from a bag. Fixed mode: ``target_pose`` names a YAML with the target and its
    pose in the base frame. Hand-eye: ``target`` on the flange (or, ``setup`` eye-in-hand,
    the camera on the flange and the target fixed), joint states from the bag."""
    try:
        frames = read_bag(bag, streams=("color", "depth"), max_frames=max_frames)
    except BagError:
        # Depth only serves the target-size check: calibrate from color alone without it.
        frames = read_bag(bag, streams=("color",), max_frames=max_frames)
    if frames.color is None or len(frames.color) == 0:
        raise CalibrationError(f"{bag}: no color frames to calibrate from")
    intr = frames.color.intrinsics
    images = list(frames.color.images)
    depths = _depths(frames)
    if mode == "fixed":
        if target_pose is None:
            raise CalibrationError(
                "fixed mode needs --target-pose YAML (the target and its pose in the base frame)"
            )
        spec, T_base_target = load_target_pose(target_pose)
        target = target or spec
        result = calibrate_fixed(
            images,
            intr.K,
            intr.D,
            target,
            T_base_target,
            stamps_ns=[int(v) for v in frames.color.stamps_ns],
            depth_m=depths,
        )
    elif mode == "hand-eye":
        if target is None or robot is None:
            raise CalibrationError("hand-eye mode needs --target SPEC and a robot")
        flange = flange or robot.config.end_effector
        poses = flange_poses(frames, robot, flange)
        result = calibrate_hand_eye(
            images,
            intr.K,
            intr.D,
            target,
            poses,
            setup=setup,
            stamps_ns=[int(v) for v in frames.color.stamps_ns],
            depth_m=depths,
        )
        result = replace(result, flange_frame=flange)
    else:
        raise CalibrationError(f"unknown mode '{mode}'; valid: fixed, hand-eye")
    return CalibrationRun(result, _overlay(images, result, target, intr.K, intr.D), frames)


@dataclass(frozen=True)
class ImagesRun:
    """A calibration from photos: the ``result``, an ``overlay`` picture, the photos'
    ``paths``, and the RMS (px) of the intrinsics estimated from them (None when given)."""

    result: CalibrationResult
    overlay: npt.NDArray[np.uint8]
    paths: tuple[Path, ...]
    intrinsics_rms_px: float | None


def calibrate_images(
    images_source: str | Path,
    *,
    mode: str,
    intrinsics: str | Path | None = None,
    poses: str | Path | None = None,
    robot: RobotModel | None = None,
    target: Target | None = None,
    target_pose: str | Path | None = None,
    flange: str | None = None,
    setup: Setup | str = Setup.EYE_TO_HAND,
) -> ImagesRun:
    """Calibrate from photos (``images_source``: a folder or a glob). ``intrinsics``: a ROS
    camera_info YAML, an OpenCV YAML/XML or a JSON file; without it they are estimated from
    the same photos (a board target is needed). Fixed mode: ``target_pose`` as for bags.
    Hand-eye: ``poses``, one flange pose per photo (xyz + quaternion) or joint positions,
    which need the ``robot``; ``flange`` names the frame they are for (default: the robot's
    end effector)."""
    from calibration.inputs import estimate_intrinsics, load_images, load_intrinsics
    from calibration.pose_files import load_poses, order_by_images

    if mode not in ("fixed", "hand-eye"):
        raise CalibrationError(f"unknown mode '{mode}'; valid: fixed, hand-eye")
    if mode == "fixed":
        if target_pose is None:
            raise CalibrationError(
                "fixed mode needs --target-pose YAML (the target and its pose in the base frame)"
            )
        spec, T_base_target = load_target_pose(target_pose)
        target = target or spec
    elif target is None or poses is None:
        raise CalibrationError(
            "hand-eye from images needs --target SPEC and --poses FILE|DIR (one flange pose "
            "per image)"
        )
    paths, images = load_images(images_source)
    flange_poses_: list[Array] = []
    if mode == "hand-eye":
        assert poses is not None
        given = order_by_images(load_poses(poses, count=len(images)), paths)
        if given.T_base_flange is not None:
            flange_poses_ = list(given.T_base_flange)
        else:
            if robot is None:
                raise CalibrationError(
                    f"{poses} holds joint positions: give the robot (--robot) to turn them "
                    "into flange poses"
                )
            assert given.joints is not None
            frame = flange or robot.config.end_effector
            flange_poses_ = [robot.frame_pose(q, frame) for q in given.joints]
    intrinsics_rms = None
    if intrinsics is not None:
        camera = load_intrinsics(intrinsics, images[0].shape)
    else:
        camera, intrinsics_rms = estimate_intrinsics(images, target)
    if mode == "fixed":
        result = calibrate_fixed(images, camera.K, camera.D, target, T_base_target)
    else:
        result = calibrate_hand_eye(images, camera.K, camera.D, target, flange_poses_, setup=setup)
        flange_frame = flange or (robot.config.end_effector if robot is not None else None)
        result = replace(result, flange_frame=flange_frame)
    overlay = _overlay(images, result, target, camera.K, camera.D)
    return ImagesRun(result, overlay, tuple(paths), intrinsics_rms)


def _overlay(
    images: list[npt.NDArray[np.uint8]],
    result: CalibrationResult,
    target: Target,
    K: Array,
    D: Array,
) -> npt.NDArray[np.uint8]:
    used = [f.index for f in result.frames if f.used] or [0]
    image = images[used[0]]
    det = detect(image, target, K, D)
    if det is None:
        return image
    pose = solve_pose(det, target, K, D)
    return draw_overlay(image, det, K, D, pose.T_cam_target, target)
