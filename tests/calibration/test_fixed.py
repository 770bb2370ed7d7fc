from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from calibration.detect import detect
from calibration.fixed import calibrate_fixed, load_target_pose
from calibration.overlay import draw_overlay, save_png
from calibration.result import Mode, load_calibration
from calibration.targets import SingleTag, TagGrid
from gaide_core.errors import CalibrationError
from gaide_core.transforms import from_xyz_rpy, transform_error
from tests.calibration.synth import K, depth_of_plane, look_at_target, render

TAG = SingleTag(5, 0.15)
# Camera 1.2 m up, looking down and forward at the table; the tag on the table, tilted.
T_BASE_CAM = from_xyz_rpy([0.1, -0.6, 1.2], [-2.3, 0.05, 0.4])
T_CAM_TAG = look_at_target([0.05, -0.03, 0.6], [0.5, 0.35, 0.2], +1.0)
T_BASE_TAG = T_BASE_CAM @ T_CAM_TAG


def test_fixed_recovers_T_base_cam(rng: np.random.Generator, tmp_path: Path) -> None:
    images = [render(TAG, T_CAM_TAG, rng) for _ in range(6)]
    # A frame taken while the tag was knocked out of place must be rejected, not averaged.
    bumped = T_CAM_TAG @ from_xyz_rpy([0.03, 0.0, 0.0], [0.0, 0.0, 0.2])
    images.insert(3, render(TAG, bumped, rng))
    stamps = [1_000_000_000 + 33_000_000 * i for i in range(len(images))]
    result = calibrate_fixed(images, K, None, TAG, T_BASE_TAG, stamps_ns=stamps)
    dt, dr = transform_error(result.T_base_cam, T_BASE_CAM)
    assert dt < 0.002 and np.degrees(dr) < 0.2, (dt * 1e3, np.degrees(dr))
    assert result.mode is Mode.FIXED
    assert [f.used for f in result.frames] == [True] * 3 + [False] + [True] * 3
    assert "from the median" in result.frames[3].reason
    assert result.frames[3].rms_px is not None and result.frames[3].rms_px > 5.0
    assert result.frames[0].stamp_ns == stamps[0]
    assert result.reprojection_rms_px < 0.5
    assert (result.width, result.height) == (images[0].shape[1], images[0].shape[0])
    back = load_calibration(result.save_yaml(tmp_path / "calib.yaml"))
    assert np.array_equal(back.T_base_cam, result.T_base_cam)


def test_fixed_with_a_tag_grid(rng: np.random.Generator) -> None:
    grid = TagGrid(3, 2, 0.05, 0.012, first_id=40)
    T_cam_grid = look_at_target([-0.09, 0.05, 0.55], [0.4, -0.3, 0.1], -1.0)
    images = [render(grid, T_cam_grid, rng) for _ in range(3)]
    result = calibrate_fixed(images, K, None, grid, T_BASE_CAM @ T_cam_grid)
    dt, dr = transform_error(result.T_base_cam, T_BASE_CAM)
    assert dt < 0.002 and np.degrees(dr) < 0.2, (dt * 1e3, np.degrees(dr))


def test_no_target_in_images(rng: np.random.Generator) -> None:
    blank = [rng.integers(0, 255, (480, 848, 3), dtype=np.uint8) for _ in range(3)]
    with pytest.raises(CalibrationError, match=r"found in 0 of 3 images.*ids seen: \[\]"):
        calibrate_fixed(blank, K, None, TAG, T_BASE_TAG)


def test_wrong_tag_id_lists_ids_seen(rng: np.random.Generator) -> None:
    images = [render(TAG, T_CAM_TAG, rng)]
    with pytest.raises(CalibrationError, match=r"tag id 3 .*ids seen: \[5\]"):
        calibrate_fixed(images, K, None, SingleTag(3, 0.15), T_BASE_TAG)


def test_wrong_size_caught_by_depth(rng: np.random.Generator) -> None:
    true_tag = SingleTag(5, 0.075)
    T_cam_tag = look_at_target([0.0, 0.02, 0.9], [0.3, 0.3, 0.0], +1.0)
    images = [render(true_tag, T_cam_tag, rng) for _ in range(2)]
    depth = depth_of_plane(T_cam_tag)
    depth += rng.normal(0, 0.004, depth.shape)  # RealSense-like noise at 0.9 m
    depth[rng.random(depth.shape) < 0.2] = 0.0  # and holes
    with pytest.raises(
        CalibrationError, match=r"0\.60 m but depth says 0\.90 m: is the tag size 0\.07[45]"
    ):
        calibrate_fixed(images, K, None, SingleTag(5, 0.05), T_BASE_TAG, depth_m=[depth, depth])
    # The right size passes the same check, and depth without data skips it.
    ok = calibrate_fixed(images, K, None, true_tag, T_BASE_TAG, depth_m=[depth, depth])
    assert ok.reprojection_rms_px < 0.5
    empty = np.full_like(depth, np.nan)
    calibrate_fixed(images, K, None, SingleTag(5, 0.05), T_BASE_TAG, depth_m=[empty, empty])
    with pytest.raises(CalibrationError, match="one per image"):
        calibrate_fixed(images, K, None, true_tag, T_BASE_TAG, depth_m=[depth])


def test_bad_inputs() -> None:
    img = np.zeros((48, 64), np.uint8)
    with pytest.raises(CalibrationError, match="no images"):
        calibrate_fixed([], K, None, TAG, T_BASE_TAG)
    with pytest.raises(CalibrationError, match="differ in size"):
        calibrate_fixed([img, img[:40]], K, None, TAG, T_BASE_TAG)
    with pytest.raises(CalibrationError, match="camera matrix K must be a finite 3x3"):
        calibrate_fixed([img], np.eye(4), None, TAG, T_BASE_TAG)
    with pytest.raises(CalibrationError, match="rigid"):
        calibrate_fixed([img], K, None, TAG, 2 * np.eye(4))
    with pytest.raises(CalibrationError, match="uint8"):
        calibrate_fixed([img.astype(np.float32)], K, None, TAG, T_BASE_TAG)  # type: ignore[list-item]


def test_load_target_pose(tmp_path: Path) -> None:
    path = tmp_path / "target.yaml"
    path.write_text(
        "target: tag36h11:id=5,size=0.15\n"
        "T_base_target: {xyz: [0.5, -0.1, 0.02], quat_xyzw: [0, 0, 0.7071067811865476, 0.7071067811865476]}\n"
    )
    target, T = load_target_pose(path)
    assert target == TAG
    assert np.allclose(T[:3, 3], [0.5, -0.1, 0.02])
    assert np.allclose(T[:3, :3] @ [1, 0, 0], [0, 1, 0])
    path.write_text(
        "target: {type: grid, markers_x: 2, markers_y: 2, marker_size: 0.04, separation: 0.01}\n"
        f"T_base_target: {{matrix: {T_BASE_TAG.tolist()}}}\n"
    )
    target, T = load_target_pose(path)
    assert target == TagGrid(2, 2, 0.04, 0.01)
    assert np.allclose(T, T_BASE_TAG)
    path.write_text(
        "target: tag36h11:id=5,size=0.15\nT_base_target: {matrix: [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}\n"
    )
    with pytest.raises(CalibrationError, match="not a rigid"):
        load_target_pose(path)
    path.write_text("target: tag36h11:id=5,size=0.15\n")
    with pytest.raises(CalibrationError, match="T_base_target"):
        load_target_pose(path)
    with pytest.raises(CalibrationError, match="does not exist"):
        load_target_pose(tmp_path / "missing.yaml")


def test_overlay(rng: np.random.Generator, tmp_path: Path) -> None:
    image = render(TAG, T_CAM_TAG, rng)
    det = detect(image, TAG, K, None)
    assert det is not None
    before = image.copy()
    out = draw_overlay(image, det, K, None, T_CAM_TAG, TAG)
    assert out.shape == image.shape and out.dtype == np.uint8
    assert np.array_equal(image, before)  # input untouched
    # The x axis is drawn red from the tag's centre towards its +x edge.
    tip = K @ (T_CAM_TAG[:3, 3] + T_CAM_TAG[:3, 0] * TAG.size / 4)
    u, v = np.round(tip[:2] / tip[2]).astype(int)
    r, g, b = out[v, u].astype(int)
    assert r > 200 and g < 80 and b < 80, out[v, u]
    path = save_png(tmp_path / "sub" / "overlay.png", out)
    saved = cv2.imread(str(path))
    assert saved is not None
    back = cv2.cvtColor(saved, cv2.COLOR_BGR2RGB)
    assert np.array_equal(back, out)
    assert list(path.parent.iterdir()) == [path]  # no temporary file left behind
