"""Depth images to 3D points: fusion over frames and vectorized deprojection.

Camera frames follow the ROS optical convention (x right, y down, z forward); a depth value
is the z coordinate of the point in the depth camera frame.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from gaide_core.camera import Intrinsics
from gaide_core.errors import PerceptionError
from gaide_core.types import Array


def fuse_depth(images: Sequence[np.ndarray], depth_units: float) -> Array:
    """Median over frames of raw depth images (H, W), zeros ignored; returns metres with
    NaN where no frame saw anything."""
    if len(images) == 0:
        raise PerceptionError("no depth frames to fuse")
    if depth_units <= 0:
        raise PerceptionError(f"depth units must be > 0 m, got {depth_units}")
    shape = images[0].shape
    if any(img.shape != shape for img in images):
        raise PerceptionError("depth frames differ in size; fuse frames of one stream only")
    stack = np.stack(images).astype(np.float32)
    stack[stack == 0] = np.nan
    if len(images) == 1:
        fused = stack[0]
    else:
        with np.errstate(all="ignore"):
            # all-NaN pixels stay NaN (numpy warns about them, which we silence)
            import warnings

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                fused = np.nanmedian(stack, axis=0)
    return fused.astype(np.float64) * depth_units


class Deprojector:
    """Precomputed pixel rays of one camera: turns depth images into points fast."""

    def __init__(self, intrinsics: Intrinsics) -> None:
        self.intrinsics = intrinsics
        v, u = np.mgrid[0 : intrinsics.height, 0 : intrinsics.width].astype(np.float64)
        pts = np.stack([u.ravel(), v.ravel()], axis=1)
        if np.any(intrinsics.D != 0) and intrinsics.distortion_model in (
            "plumb_bob",
            "rational_polynomial",
        ):
            # RealSense depth streams report zero distortion; others get undistorted rays.
            import cv2

            und = cv2.undistortPoints(pts.reshape(-1, 1, 2), intrinsics.K, intrinsics.D)
            xy = und.reshape(-1, 2)
        else:
            xy = np.stack(
                [
                    (pts[:, 0] - intrinsics.cx) / intrinsics.fx,
                    (pts[:, 1] - intrinsics.cy) / intrinsics.fy,
                ],
                axis=1,
            )
        self.rays = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)  # (H*W, 3), z = 1

    def points(
        self, depth_m: Array, min_depth: float = 0.1, max_depth: float = 10.0
    ) -> tuple[Array, npt.NDArray[np.int64]]:
        """Points (M, 3) in the camera frame for valid pixels, and their flat pixel indices."""
        intr = self.intrinsics
        if depth_m.shape != (intr.height, intr.width):
            raise PerceptionError(
                f"depth image is {depth_m.shape[1]}x{depth_m.shape[0]}, the intrinsics are for "
                f"{intr.width}x{intr.height}"
            )
        z = depth_m.ravel()
        valid = np.flatnonzero(np.isfinite(z) & (z >= min_depth) & (z <= max_depth))
        return self.rays[valid] * z[valid, None], valid


def project(points: Array, intrinsics: Intrinsics) -> tuple[Array, npt.NDArray[np.bool_]]:
    """Pixel coordinates (M, 2) of camera-frame points (M, 3) and which land in the image
    in front of the camera (distortion applied when the model has it)."""
    z = points[:, 2]
    front = z > 1e-6
    safe = np.where(front, z, 1.0)
    xy = points[:, :2] / safe[:, None]
    if np.any(intrinsics.D != 0):
        import cv2

        uv = cv2.projectPoints(
            np.concatenate([xy, np.ones((len(xy), 1))], axis=1),
            np.zeros(3),
            np.zeros(3),
            intrinsics.K,
            intrinsics.D,
        )[0].reshape(-1, 2)
    else:
        uv = np.stack(
            [xy[:, 0] * intrinsics.fx + intrinsics.cx, xy[:, 1] * intrinsics.fy + intrinsics.cy],
            axis=1,
        )
    inside = front & (uv[:, 0] >= -0.5) & (uv[:, 1] >= -0.5)
    inside &= (uv[:, 0] < intrinsics.width - 0.5) & (uv[:, 1] < intrinsics.height - 0.5)
    return np.asarray(uv, dtype=np.float64), inside


_DEPROJECTORS: dict[bytes, Deprojector] = {}


def deprojector_for(intrinsics: Intrinsics) -> Deprojector:
    """A cached Deprojector per camera: its rays cost as much as a whole frame's points."""
    key = np.array([intrinsics.width, intrinsics.height], float).tobytes() + intrinsics.K.tobytes()
    key += intrinsics.D.tobytes() + intrinsics.distortion_model.encode()
    if key not in _DEPROJECTORS:
        if len(_DEPROJECTORS) > 8:
            _DEPROJECTORS.clear()
        _DEPROJECTORS[key] = Deprojector(intrinsics)
    return _DEPROJECTORS[key]
