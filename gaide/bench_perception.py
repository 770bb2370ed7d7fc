"""``gaide bench perception``: calibration and cloud accuracy on freshly recorded synthetic
bags, and the speed of bag -> base-frame cloud.

- ``fixed_err_mm`` / ``fixed_err_deg``: fixed-target calibration (ChArUco 9x6 on the table,
  5 frames) versus the recorder's ground truth T_base_cam.
- ``handeye_err_mm`` / ``handeye_err_deg``: eye-to-hand calibration (ChArUco on the flange,
  12 poses, joint states from the bag).
- ``eye_in_hand_err_mm`` / ``eye_in_hand_err_deg``: eye-in-hand calibration (camera on the
  flange, a DICT_6X6_250 ChArUco board fixed on the table, ``handeye_poses`` rendered photos
  from random flange poses) versus the true ``T_flange_cam``; ``eye_in_hand_std_mm`` /
  ``_deg``: the standard deviation the calibration reports for itself.
- ``detector_recall_vs_reference``, ``corner_err_px``, ``dict_cases_found``: see
  ``gaide.bench_detector`` (needs the pupil-apriltags reference detector).
- ``cloud_median_err_mm``: median distance of the reconstructed cloud (with the estimated fixed
  calibration, robot removed) to the true surfaces.
- ``frames_per_s``: 640x480 depth frames per second through the pipeline's own path: read a
  30-frame recording, fuse its depth (median), deproject, move to base, crop, voxel filter,
  remove the robot and outliers. ``single_frame_clouds_per_s``: the same with every frame
  turned into a cloud of its own (no fusion).
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from calibration.hand_eye import calibrate_hand_eye
from calibration.targets import Charuco, target_from_dict
from gaide.flows.calibrate import calibrate_bag
from gaide.flows.perceive import perceive_bag
from gaide.synthetic.record import load_ground_truth, record_scene, target_pose_path
from gaide.synthetic.scene import SyntheticScene, fixed_scene, hand_eye_scene
from gaide_core.errors import PerceptionError
from gaide_core.transforms import from_xyz_rpy, invert, transform_error
from gaide_core.types import Array
from perception.bag_reader import read_bag
from perception.cloud import scene_cloud
from perception.cloud_cfg import CloudCfg
from perception.frames import ImageStream
from planning.checker import make_checker
from planning.primitives import PrimitiveWorld
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel


def run_perception_benchmark(
    robot: RobotModel,
    spheres: SphereModel,
    *,
    seed: int = 0,
    speed_frames: int = 20,
    handeye_poses: int = 12,
    progress: Any = None,
) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        scene = fixed_scene(robot, rng, frames=5)
        T_base_cam = _fixed_target(scene, robot, spheres, folder, rng, progress, out)
        _hand_eye(robot, spheres, folder, rng, handeye_poses, progress, out)
        out.update(eye_in_hand_benchmark(rng, poses=handeye_poses))
        _speed(scene, T_base_cam, robot, spheres, folder, rng, speed_frames, progress, out)
    return out


def _fixed_target(
    scene: SyntheticScene,
    robot: RobotModel,
    spheres: SphereModel,
    folder: Path,
    rng: np.random.Generator,
    progress: Any,
    out: dict[str, Any],
) -> Array:
    """Calibrate a recording of ``scene`` from its fixed target, and perceive its cloud:
    the camera's error against the truth and the cloud's distance to the true obstacles
    into ``out``. Returns the calibrated camera pose (base frame)."""
    bag, truth = record_scene(scene, robot, folder / "fixed.bag", rng, progress=progress)
    gt = load_ground_truth(truth)
    run = calibrate_bag(bag, mode="fixed", target_pose=target_pose_path(bag))
    dt, dr = transform_error(run.result.T_base_cam, np.asarray(gt["T_base_cam"]["matrix"]))
    out.update(
        fixed_err_mm=dt * 1e3,
        fixed_err_deg=float(np.degrees(dr)),
        fixed_rms_px=run.result.reprojection_rms_px,
    )
    cloud, _, _ = perceive_bag(bag, run.result, robot, spheres)
    err = np.abs(PrimitiveWorld.from_dict(gt["world"]).distance(cloud.points))
    out.update(
        cloud_median_err_mm=float(np.median(err)) * 1e3,
        cloud_p95_err_mm=float(np.percentile(err, 95)) * 1e3,
        cloud_points=len(cloud),
    )
    return run.result.T_base_cam


def _hand_eye(
    robot: RobotModel,
    spheres: SphereModel,
    folder: Path,
    rng: np.random.Generator,
    poses: int,
    progress: Any,
    out: dict[str, Any],
) -> None:
    """Eye-to-hand calibration of a recording with the target on the flange at ``poses``
    poses: the camera's error against the truth, the fit and the methods' spread into
    ``out``."""
    he = hand_eye_scene(robot, lambda w: make_checker(robot, spheres, w), rng, states=poses)
    bag, truth = record_scene(he, robot, folder / "hand_eye.bag", rng, progress=progress)
    gt = load_ground_truth(truth)
    run = calibrate_bag(bag, mode="hand-eye", robot=robot, target=target_from_dict(gt["target"]))
    dt, dr = transform_error(run.result.T_base_cam, np.asarray(gt["T_base_cam"]["matrix"]))
    spread = run.result.spread
    out.update(
        handeye_err_mm=dt * 1e3,
        handeye_err_deg=float(np.degrees(dr)),
        handeye_rms_px=run.result.reprojection_rms_px,
        handeye_frames_used=sum(f.used for f in run.result.frames),
        handeye_methods_spread_mm=None if spread is None else spread.translation_mm,
        handeye_methods_spread_deg=None if spread is None else spread.rotation_deg,
    )


def _speed(
    scene: SyntheticScene,
    T_base_cam: Array,
    robot: RobotModel,
    spheres: SphereModel,
    folder: Path,
    rng: np.random.Generator,
    frames_n: int,
    progress: Any,
    out: dict[str, Any],
) -> None:
    """Perception's speed on a longer recording of ``scene``: the pipeline's own path (read
    every frame, fuse, one cloud), and every frame turned into a cloud on its own."""
    speed_scene = replace(scene, joint_states=np.repeat(scene.joint_states[:1], frames_n, axis=0))
    bag, _ = record_scene(speed_scene, robot, folder / "speed.bag", rng, progress=progress)
    checker = make_checker(robot, spheres)
    robot_spheres = (checker.sphere_centers(scene.joint_states[:1])[0], checker.radii)
    cfg = CloudCfg(max_frames=frames_n)
    t0 = time.perf_counter()
    frames = read_bag(bag, streams=("depth",))
    scene_cloud(frames, T_base_cam, cfg, robot_spheres=robot_spheres, colored=False)
    fused_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    frames = read_bag(bag, streams=("depth",))
    depth = frames.depth
    if depth is None:
        raise PerceptionError(f"{bag}: the recorder wrote no depth")
    for i in range(len(depth)):
        single = replace(
            frames,
            depth=ImageStream(
                depth.intrinsics, depth.images[i : i + 1], depth.stamps_ns[i : i + 1]
            ),
        )
        scene_cloud(single, T_base_cam, cfg, robot_spheres=robot_spheres, colored=False)
    single_s = time.perf_counter() - t0
    out.update(
        frames_per_s=len(depth) / fused_s,
        single_frame_clouds_per_s=len(depth) / single_s,
        speed_frames=len(depth),
    )


#: The eye-in-hand benchmark's truth: the camera on the flange, the board on the table.
EIH_T_FLANGE_CAM = from_xyz_rpy([0.04, -0.07, 0.06], [0.02, 0.08, -1.52])
EIH_T_BASE_BOARD = from_xyz_rpy([0.55, 0.12, 0.01], [0.0, 0.0, 0.35])
EIH_BOARD = Charuco(7, 5, 0.04, 0.03, "DICT_6X6_250")


def eye_in_hand_views(
    rng: np.random.Generator, poses: int = 12
) -> tuple[list[npt.NDArray[np.uint8]], list[Array], Array]:
    """Rendered photos of ``EIH_BOARD`` from a camera on the flange: (gray images, the true
    ``T_base_flange`` of each, the camera's K)."""
    from gaide.synthetic.marker_images import camera_matrix, centred, facing_camera, render

    K = camera_matrix(848, 480, 610.0)
    images, flanges = [], []
    for _ in range(poses):
        xyz = [rng.uniform(-0.04, 0.04), rng.uniform(-0.03, 0.03), rng.uniform(0.45, 0.65)]
        T_cam_board = centred(EIH_BOARD, facing_camera(xyz, rng.uniform(-0.45, 0.45, 3), -1.0))
        flanges.append(EIH_T_BASE_BOARD @ invert(T_cam_board) @ invert(EIH_T_FLANGE_CAM))
        images.append(render([(EIH_BOARD, T_cam_board)], K, rng, size=(848, 480)))
    return images, flanges, K


def eye_in_hand_benchmark(rng: np.random.Generator, *, poses: int = 12) -> dict[str, float]:
    """Eye-in-hand calibration on rendered photos of a fixed board (see the module doc)."""
    images, flanges, K = eye_in_hand_views(rng, poses)
    result = calibrate_hand_eye(images, K, None, EIH_BOARD, flanges, setup="eye-in-hand")
    assert result.T_flange_cam is not None and result.uncertainty is not None
    dt, dr = transform_error(result.T_flange_cam, EIH_T_FLANGE_CAM)
    return {
        "eye_in_hand_err_mm": dt * 1e3,
        "eye_in_hand_err_deg": float(np.degrees(dr)),
        "eye_in_hand_std_mm": result.uncertainty.translation_mm,
        "eye_in_hand_std_deg": result.uncertainty.rotation_deg,
        "eye_in_hand_rms_px": result.reprojection_rms_px,
    }
