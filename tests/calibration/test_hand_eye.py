from __future__ import annotations

import numpy as np
import pytest

from calibration.hand_eye import METHODS, calibrate_hand_eye
from calibration.result import Mode, Setup
from calibration.targets import Charuco, SingleTag
from gaide_core.errors import CalibrationError
from gaide_core.transforms import from_xyz_rpy, invert, make_transform, transform_error
from tests.calibration.synth import K, look_at_target, render

TAG = SingleTag(7, 0.08)
T_FLANGE_TAG = from_xyz_rpy([0.01, 0.02, 0.03], [0.0, 0.0, 0.3])


def _camera() -> np.ndarray:  # type: ignore[type-arg]
    """Camera 1.1 m in front of the robot, 0.55 m up, looking back and down at it."""
    z = np.array([-1.0, 0.0, -0.45])
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return make_transform(np.column_stack([x, np.cross(z, x), z]), np.array([1.1, 0.05, 0.55]))


T_BASE_CAM = _camera()


def _scene(
    rng: np.random.Generator, n: int, rpy_range: float = 0.6
) -> tuple[list[np.ndarray], list[np.ndarray]]:  # type: ignore[type-arg]
    """Images and flange poses with the tag at random places and turns in front of the camera."""
    images, flanges = [], []
    for _ in range(n):
        p = [rng.uniform(-0.12, 0.12), rng.uniform(-0.08, 0.08), rng.uniform(0.45, 0.7)]
        T_cam_tag = look_at_target(p, rng.uniform(-rpy_range, rpy_range, 3), +1.0)
        flanges.append(T_BASE_CAM @ T_cam_tag @ invert(T_FLANGE_TAG))
        images.append(render(TAG, T_cam_tag, rng))
    return images, flanges


def test_hand_eye_recovers_T_base_cam(rng: np.random.Generator) -> None:
    images, flanges = _scene(rng, 12)
    stamps = list(range(0, 12 * 10**8, 10**8))
    result = calibrate_hand_eye(images, K, None, TAG, flanges, stamps_ns=stamps)
    dt, dr = transform_error(result.T_base_cam, T_BASE_CAM)
    assert dt < 0.005 and np.degrees(dr) < 0.5, (dt * 1e3, np.degrees(dr))
    assert result.mode is Mode.HAND_EYE
    assert result.T_flange_target is not None
    dt, dr = transform_error(result.T_flange_target, T_FLANGE_TAG)
    assert dt < 0.005 and np.degrees(dr) < 0.5
    # Each closed-form method is reported, and (eye-to-hand inversion right) each is close.
    assert [m.name for m in result.methods] == list(METHODS)
    worst_t, worst_r = 0.0, 0.0
    for m in result.methods:
        t, r = transform_error(m.T_base_cam, T_BASE_CAM)
        assert t < 0.01 and np.degrees(r) < 1.0, (m.name, t * 1e3, np.degrees(r))
        worst_t, worst_r = max(worst_t, t), max(worst_r, r)
    assert result.spread is not None
    assert 0 < result.spread.translation_mm <= 2e3 * worst_t
    assert 0 < result.spread.rotation_deg <= 2 * np.degrees(worst_r)
    assert result.reprojection_rms_px < 0.5
    assert all(f.used for f in result.frames) and len(result.frames) == 12
    assert [f.stamp_ns for f in result.frames] == stamps


def test_bad_robot_pose_rejected(rng: np.random.Generator) -> None:
    images, flanges = _scene(rng, 10)
    flanges[4] = flanges[4] @ from_xyz_rpy([0.02, 0.0, 0.0], [0.0, 0.1, 0.0])  # stale pose
    result = calibrate_hand_eye(images, K, None, TAG, flanges)
    assert not result.frames[4].used and "after refinement" in result.frames[4].reason
    assert sum(f.used for f in result.frames) == 9
    dt, dr = transform_error(result.T_base_cam, T_BASE_CAM)
    assert dt < 0.005 and np.degrees(dr) < 0.5


def test_fewer_than_three_poses(rng: np.random.Generator) -> None:
    images, flanges = _scene(rng, 2)
    with pytest.raises(CalibrationError, match="2 distinct flange poses"):
        calibrate_hand_eye(images * 3, K, None, TAG, flanges * 3)


def test_rotation_about_one_axis_is_degenerate(rng: np.random.Generator) -> None:
    images, flanges = [], []
    for k in range(6):
        # The flange turns about its own z only (one wrist joint), at several places.
        spin = from_xyz_rpy([0.0, 0.0, 0.0], [0.0, 0.0, 0.25 * k])
        T_cam_tag = look_at_target([0.02 * k - 0.05, 0.0, 0.55], [0.3, -0.2, 0.0], +1.0)
        T_base_flange = T_BASE_CAM @ T_cam_tag @ invert(T_FLANGE_TAG) @ spin
        flanges.append(T_base_flange)
        images.append(render(TAG, invert(T_BASE_CAM) @ T_base_flange @ T_FLANGE_TAG, rng))
    with pytest.raises(CalibrationError, match="about one axis"):
        calibrate_hand_eye(images, K, None, TAG, flanges)


def test_too_little_rotation(rng: np.random.Generator) -> None:
    images, flanges = _scene(rng, 5, rpy_range=0.01)
    with pytest.raises(CalibrationError, match="too little rotation"):
        calibrate_hand_eye(images, K, None, TAG, flanges)


def test_target_missing_in_too_many_frames(rng: np.random.Generator) -> None:
    images, flanges = _scene(rng, 8)
    for i in range(5):
        images[i] = rng.integers(0, 255, images[i].shape, dtype=np.uint8)
    with pytest.raises(CalibrationError, match=r"found in 3 of 8 images"):
        calibrate_hand_eye(images, K, None, TAG, flanges)


def test_pose_count_must_match(rng: np.random.Generator) -> None:
    images, flanges = _scene(rng, 3)
    with pytest.raises(CalibrationError, match="one per image"):
        calibrate_hand_eye(images, K, None, TAG, flanges[:2])


T_FLANGE_CAM = from_xyz_rpy([0.03, -0.06, 0.05], [0.0, 0.05, -1.5])
T_BASE_BOARD = from_xyz_rpy([0.6, 0.1, 0.0], [0.0, 0.0, 0.4])
BOARD = Charuco(7, 5, 0.04, 0.03, "DICT_6X6_250")


def _eye_in_hand_scene(
    rng: np.random.Generator, n: int
) -> tuple[list[np.ndarray], list[np.ndarray]]:  # type: ignore[type-arg]
    """A camera on the flange looking at a ChArUco board fixed on the table."""
    images, flanges = [], []
    for _ in range(n):
        p = [rng.uniform(-0.18, -0.1), rng.uniform(-0.12, -0.06), rng.uniform(0.45, 0.65)]
        T_cam_board = look_at_target(p, rng.uniform(-0.45, 0.45, 3), -1.0)
        flanges.append(T_BASE_BOARD @ invert(T_cam_board) @ invert(T_FLANGE_CAM))
        images.append(render(BOARD, T_cam_board, rng))
    return images, flanges


def test_eye_in_hand_recovers_T_flange_cam(rng: np.random.Generator) -> None:
    images, flanges = _eye_in_hand_scene(rng, 10)
    result = calibrate_hand_eye(images, K, None, BOARD, flanges, setup="eye-in-hand")
    assert result.setup is Setup.EYE_IN_HAND
    assert result.T_flange_cam is not None and result.T_base_target is not None
    dt, dr = transform_error(result.T_flange_cam, T_FLANGE_CAM)
    assert dt < 0.002 and np.degrees(dr) < 0.2, (dt * 1e3, np.degrees(dr))
    dt, dr = transform_error(result.T_base_target, T_BASE_BOARD)
    assert dt < 0.002 and np.degrees(dr) < 0.2, (dt * 1e3, np.degrees(dr))
    # T_base_cam: the camera where the first image was taken.
    dt, _ = transform_error(result.T_base_cam, flanges[0] @ T_FLANGE_CAM)
    assert dt < 0.002
    # The standard deviation is small on clean data and covers the true error.
    assert result.uncertainty is not None
    assert 0 < result.uncertainty.translation_mm < 1.0
    assert 0 < result.uncertainty.rotation_deg < 0.1
    assert len(result.uncertainty.translation_axes_mm) == 3
    assert result.T_flange_target is None


def test_eye_to_hand_reports_uncertainty_that_grows_with_noise(rng: np.random.Generator) -> None:
    images, flanges = _scene(rng, 10)
    clean = calibrate_hand_eye(images, K, None, TAG, flanges)
    assert clean.setup is Setup.EYE_TO_HAND and clean.uncertainty is not None
    jitter = [T @ from_xyz_rpy(rng.normal(0, 0.002, 3), rng.normal(0, 0.004, 3)) for T in flanges]
    noisy = calibrate_hand_eye(images, K, None, TAG, jitter)
    assert noisy.uncertainty is not None
    assert noisy.uncertainty.translation_mm > 2 * clean.uncertainty.translation_mm
    dt, _ = transform_error(noisy.T_base_cam, T_BASE_CAM)
    assert dt * 1e3 < 5 * noisy.uncertainty.translation_mm


def test_unknown_setup(rng: np.random.Generator) -> None:
    images, flanges = _scene(rng, 3)
    with pytest.raises(CalibrationError, match="eye-in-hand"):
        calibrate_hand_eye(images, K, None, TAG, flanges, setup="eye-on-wrist")
