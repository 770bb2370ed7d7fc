"""Real photos of a 6.5 cm tag36h11 tag (../shared/data/apriltag, see SOURCES.md there)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml

from calibration.detect import detect, scan
from calibration.fixed import calibrate_fixed
from calibration.pnp import solve_pose
from calibration.targets import SingleTag
from gaide_core.errors import CalibrationError
from tests.conftest import shared_data


def _truth() -> dict:  # type: ignore[type-arg]
    return yaml.safe_load(shared_data("apriltag/ground_truth.yaml").read_text())


def _rgb(name: str) -> np.ndarray:  # type: ignore[type-arg]
    bgr = cv2.imread(str(shared_data(f"apriltag/{name}")), cv2.IMREAD_COLOR)
    assert bgr is not None
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def _series() -> tuple[list[int], dict[int, np.ndarray], np.ndarray]:  # type: ignore[type-arg]
    truth = _truth()
    series = truth["rotation_series"]
    degrees = list(series["degrees"])
    images = {d: _rgb(series["files"].format(deg=d)) for d in degrees}
    return degrees, images, np.array(series["K"], float).reshape(3, 3)


def test_tag_found_in_every_rotation_photo() -> None:
    degrees, images, K = _series()
    tag = SingleTag(76, _truth()["tag_size_m"])
    for d in degrees:
        det = detect(images[d], tag, K, None)
        assert det is not None, f"tag 76 not found at {d} deg"
        pose = solve_pose(det, tag, K, None)
        # The tag stays at the same place: about 0.21 m in front of the camera.
        assert 0.15 < pose.T_cam_target[2, 3] < 0.3


def test_sample_photo_tags_found_and_wrong_id_named() -> None:
    truth = _truth()["sample"]
    image = _rgb(truth["file"])
    assert image.shape[:2] == (truth["height"], truth["width"])
    K = np.array(truth["K"], float).reshape(3, 3)
    seen = scan(image, SingleTag(76, 0.065), K).foreign_ids
    assert len(seen) >= 4  # a road scene with several tags
    for tag_id in seen:
        tag = SingleTag(tag_id, 0.065)
        pose = solve_pose(detect(image, tag, K, None) or pytest.fail(f"{tag_id}"), tag, K)
        assert 0.05 < pose.T_cam_target[2, 3] < 3.0
    with pytest.raises(CalibrationError, match=r"tag id 76 .*ids seen: \[" + str(min(seen))):
        calibrate_fixed([image], K, None, SingleTag(76, 0.065), np.eye(4))


def test_rotation_series_turn_angles() -> None:
    """The turn about the vertical axis from PnP, relative to the 0-degree photo, matches each
    file's angle within 3 degrees.

    Intrinsics: ground_truth.yaml's K has its principal point exactly at the image centre
    (528, 396), a placeholder for rectified photos; with it the near-frontal photos come out
    up to 6 degrees off, because the pose of a small, nearly frontal tag hangs on the
    principal point. So K (fx, fy, cx, cy; no distortion, the photos are rectified) is first
    refined from the series itself, starting from the yaml's K; the turn angles play no
    part in that fit. Sign: a positive file angle turns the tag counter-clockwise seen from
    above (about the upward vertical), read off the photos.
    """
    degrees, images, K_yaml = _series()
    tag = SingleTag(76, _truth()["tag_size_m"])
    dets = {d: detect(images[d], tag, K_yaml, None) for d in degrees}
    assert all(det is not None for det in dets.values())
    obj = [tag.marker_corners(76).astype(np.float32)] * len(degrees)
    img = [dets[d].image_points.astype(np.float32).reshape(-1, 1, 2) for d in degrees]  # type: ignore[union-attr]
    flags = (
        cv2.CALIB_USE_INTRINSIC_GUESS
        | cv2.CALIB_FIX_K1
        | cv2.CALIB_FIX_K2
        | cv2.CALIB_FIX_K3
        | cv2.CALIB_ZERO_TANGENT_DIST
    )
    h, w = images[0].shape[:2]
    rms, K, *_ = cv2.calibrateCamera(obj, img, (w, h), K_yaml.copy(), np.zeros(5), flags=flags)
    assert rms < 0.5
    assert K[0, 0] == pytest.approx(K_yaml[0, 0], rel=0.05)
    assert K[1, 1] == pytest.approx(K_yaml[1, 1], rel=0.05)

    x_axes = {}
    for d in degrees:
        pose = solve_pose(dets[d], tag, K, None)  # type: ignore[arg-type]
        x_axes[d] = pose.T_cam_target[:3, 0]
    # The tag turns about the vertical, so its x axis stays horizontal: the vertical is the
    # normal of the plane the x axes span, taken pointing up in the image (-y of the camera).
    up = np.linalg.svd(np.array(list(x_axes.values())))[2][-1]
    up = up if up[1] < 0 else -up
    x0 = x_axes[0]
    for d in degrees:
        turn = np.degrees(np.arctan2(np.dot(np.cross(x0, x_axes[d]), up), np.dot(x0, x_axes[d])))
        assert turn == pytest.approx(d, abs=3.0), f"file {d} deg, PnP {turn:.1f} deg"
