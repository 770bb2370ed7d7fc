"""An image to check a calibration by eye: detected points, tag outlines and target axes."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from calibration.detect import Detection
from calibration.pnp import dist_coeffs, project
from calibration.targets import Charuco, SingleTag, Target
from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import CalibrationError
from gaide_core.types import Array

GREEN, RED = (0, 200, 0), (255, 40, 40)  # RGB


def _axis_length(target: Target) -> float:
    """Axis length (m): half the tag, or a whole marker/square for a board."""
    if isinstance(target, SingleTag):
        return target.size / 2
    if isinstance(target, Charuco):
        return target.square_size
    return target.marker_size


def draw_overlay(
    image: npt.NDArray[np.uint8],
    detection: Detection,
    K: Array,
    D: Array | None,
    T_cam_target: Array,
    target: Target,
) -> npt.NDArray[np.uint8]:
    """RGB copy of ``image`` with the tags' outlines (green), the detected points (green
    dots), the points reprojected at ``T_cam_target`` (red crosses) and the target's axes
    (x red, y green, z blue; ``cv2.drawFrameAxes``). ``image``: gray or RGB uint8."""
    img = np.asarray(image)
    if img.dtype != np.uint8 or img.ndim not in (2, 3):
        raise CalibrationError(
            f"overlay needs a gray or RGB uint8 image, got {img.dtype} {img.shape}"
        )
    out = cv2.cvtColor(img, cv2.COLOR_GRAY2RGB) if img.ndim == 2 else img[:, :, :3].copy()
    scale = max(1, round(max(out.shape[:2]) / 640))
    for quad in detection.marker_corners:
        cv2.polylines(out, [np.round(quad).astype(np.int32)], True, GREEN, scale, cv2.LINE_AA)
    for u, v in detection.image_points:
        cv2.circle(out, (round(u), round(v)), 2 * scale, GREEN, -1, cv2.LINE_AA)
    if len(detection.object_points):
        for u, v in project(K, D, T_cam_target, detection.object_points):
            cv2.drawMarker(out, (round(u), round(v)), RED, cv2.MARKER_CROSS, 6 * scale, scale)
    rvec = cv2.Rodrigues(np.ascontiguousarray(T_cam_target[:3, :3]))[0]
    # drawFrameAxes draws x in red only for BGR images: swap so the colours read right in RGB.
    bgr = np.ascontiguousarray(out[:, :, ::-1])
    cv2.drawFrameAxes(
        bgr, K, dist_coeffs(D), rvec, T_cam_target[:3, 3], _axis_length(target), 2 * scale
    )
    rgb: npt.NDArray[np.uint8] = np.ascontiguousarray(bgr[:, :, ::-1])
    return rgb


def save_png(path: str | os.PathLike[str], image: npt.NDArray[np.uint8]) -> Path:
    """Write an RGB (or gray) uint8 image as PNG, atomically (temporary file, rename)."""
    img = np.asarray(image)
    if img.dtype != np.uint8 or img.ndim not in (2, 3):
        raise CalibrationError(
            f"save_png needs a gray or RGB uint8 image, got {img.dtype} {img.shape}"
        )
    if img.ndim == 3:
        img = np.asarray(cv2.cvtColor(img, cv2.COLOR_RGB2BGR), np.uint8)
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise CalibrationError(f"cannot encode a {img.shape} image as PNG")
    return write_bytes_atomic(path, buf.tobytes(), CalibrationError)
