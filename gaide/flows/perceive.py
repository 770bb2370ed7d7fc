"""Bag + calibration -> the scene cloud in the base frame, without the robot's own points."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from calibration.result import CalibrationResult, load_calibration
from gaide_core.errors import PerceptionError
from gaide_core.types import Array
from perception.bag_reader import read_bag
from perception.cloud import SceneCloud, scene_cloud
from perception.cloud_cfg import CloudCfg
from perception.frames import Frames
from planning.checker import make_checker
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel

log = logging.getLogger(__name__)


def recorded_configuration(frames: Frames, robot: RobotModel) -> Array | None:
    """The robot's joint vector at the first depth frame, from the bag's joint states."""
    js = frames.joint_states
    if js is None or len(js.stamps_ns) == 0 or frames.depth is None:
        return None
    missing = [n for n in robot.joint_names if n not in js.names]
    if missing:
        raise PerceptionError(f"{frames.source}: joint states lack joints {missing}")
    order = [js.names.index(n) for n in robot.joint_names]
    return js.at(int(frames.depth.stamps_ns[0]))[order]


def check_intrinsics(calib: CalibrationResult, frames: Frames) -> None:
    """Refuse a calibration made for another camera (size or focal length differs)."""
    if frames.color is None:
        return
    intr = frames.color.intrinsics
    if (calib.width, calib.height) != (intr.width, intr.height) or not np.allclose(
        calib.K, intr.K, rtol=0.01
    ):
        raise PerceptionError(
            f"the calibration is for a {calib.width}x{calib.height} camera with fx={calib.K[0, 0]:.1f}; "
            f"{frames.source}'s color stream is {intr.width}x{intr.height} with fx={intr.fx:.1f}"
        )


def perceive_bag(
    bag: str | Path,
    calibration: str | Path | CalibrationResult | Array,
    robot: RobotModel,
    spheres: SphereModel,
    cfg: CloudCfg | None = None,
    *,
    joints: Array | None = None,
    self_filter: bool = True,
    default_extrinsics: bool = False,
) -> tuple[SceneCloud, Frames, Array | None]:
    """The scene cloud of ``bag``; returns (cloud, frames, joint vector used for the
    self-filter or None). ``calibration``: a calibration YAML, a result, or a 4x4 T_base_cam.
    ``default_extrinsics``: a bag without the depth-to-color extrinsics is read with the
    identity (see :func:`perception.bag_reader.read_bag`) instead of refused."""
    cfg = cfg or CloudCfg()
    frames = read_bag(
        bag,
        streams=("depth",) if isinstance(calibration, np.ndarray) else ("depth", "color"),
        max_frames=cfg.max_frames,
        default_extrinsics=default_extrinsics,
    )
    if isinstance(calibration, np.ndarray):
        T_base_cam = calibration
    else:
        calib = (
            calibration
            if isinstance(calibration, CalibrationResult)
            else load_calibration(calibration)
        )
        check_intrinsics(calib, frames)
        T_base_cam = calib.T_base_cam
        if calib.T_flange_cam is not None:
            # Eye-in-hand: the camera is where the flange holds it at the recorded joints.
            q_cam = joints if joints is not None else recorded_configuration(frames, robot)
            if q_cam is None:
                raise PerceptionError(
                    f"{bag}: the calibration is eye-in-hand (camera on the flange), so the "
                    "camera pose needs the robot's joints: record joint states or give --joints"
                )
            q_cam = robot.check_configuration(q_cam, "joints for the camera pose")
            flange = calib.flange_frame or robot.config.end_effector
            T_base_cam = robot.frame_pose(q_cam, flange) @ calib.T_flange_cam
    # the bag's joint states matter only to the self-filter
    q = joints if joints is not None or not self_filter else recorded_configuration(frames, robot)
    robot_spheres = None
    if self_filter:
        if q is None:
            log.warning("%s has no joint states and none were given: robot points are kept", bag)
        else:
            q = robot.check_configuration(q, "recorded joint state")
            checker = make_checker(robot, spheres)
            robot_spheres = (checker.sphere_centers(q[None])[0], checker.radii)
    cloud = scene_cloud(frames, T_base_cam, cfg, robot_spheres=robot_spheres)
    return cloud, frames, q
