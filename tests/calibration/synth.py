"""Synthetic camera images of a calibration target, for the tests.

A pinhole camera (no distortion) looks at the target's texture lying on the plane z = 0 of
the target frame; ``cv2.warpPerspective`` paints it, supersampled and averaged down (so edges
are anti-aliased like a real sensor's), over a noisy background, with blur and pixel noise.
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from calibration.targets import Target
from gaide_core.transforms import from_xyz_rpy, make_transform
from gaide_core.types import Array

Image = npt.NDArray[np.uint8]

WIDTH, HEIGHT = 848, 480
K = np.array([[610.0, 0.0, 423.5], [0.0, 610.0, 239.5], [0.0, 0.0, 1.0]])
SUPERSAMPLE = 3


def texture_homography(
    target: Target, px_per_m: float, K_cam: Array, T_cam_target: Array
) -> tuple[Image, Array]:
    """The target's texture and the homography from its pixels (c, r) to camera pixels."""
    tex = target.texture(px_per_m)
    x_min, _, _, y_max = tex.extent
    # Texture pixel (c, r) -> target-frame (x, y, 1), from TargetTexture's convention.
    A = np.array(
        [
            [1 / px_per_m, 0, x_min + 0.5 / px_per_m],
            [0, -1 / px_per_m, y_max - 0.5 / px_per_m],
            [0, 0, 1],
        ]
    )
    Rt = np.column_stack([T_cam_target[:3, 0], T_cam_target[:3, 1], T_cam_target[:3, 3]])
    return tex.image, K_cam @ Rt @ A


def render(
    target: Target,
    T_cam_target: Array,
    rng: np.random.Generator,
    *,
    K_cam: Array = K,
    size: tuple[int, int] = (WIDTH, HEIGHT),
    noise: float = 2.0,
    blur: float = 0.6,
) -> Image:
    """(H, W, 3) RGB uint8 image of ``target`` at ``T_cam_target`` (camera optical frame)."""
    w, h = size
    s = SUPERSAMPLE
    # Supersampled camera: pixel centre u maps to s*u + (s-1)/2.
    S = np.array([[s, 0, (s - 1) / 2], [0, s, (s - 1) / 2], [0, 0, 1.0]])
    dist = float(T_cam_target[2, 3])
    px_per_m = 1.5 * s * K_cam[0, 0] / max(dist, 0.05)
    tex, H = texture_homography(target, px_per_m, S @ K_cam, T_cam_target)
    coarse = rng.uniform(60, 200, (h // 8 + 1, w // 8 + 1)).astype(np.float32)
    background = cv2.resize(coarse, (w * s, h * s), interpolation=cv2.INTER_CUBIC)
    warped = cv2.warpPerspective(
        tex.astype(np.float32), H, (w * s, h * s), flags=cv2.INTER_LINEAR, borderValue=-1.0
    )
    big = np.where(warped >= 0, warped, background)
    img = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA)
    if blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur)
    img = img + rng.normal(0, noise, img.shape)
    gray = np.clip(np.round(img), 0, 255).astype(np.uint8)
    return np.repeat(gray[:, :, None], 3, axis=2)


def depth_of_plane(
    T_cam_target: Array, K_cam: Array = K, size: tuple[int, int] = (WIDTH, HEIGHT)
) -> Array:
    """(H, W) depth (m, z along the optical axis) of the target's plane z = 0, NaN where the
    ray misses it (behind the camera)."""
    w, h = size
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    rays = np.stack(
        [(u - K_cam[0, 2]) / K_cam[0, 0], (v - K_cam[1, 2]) / K_cam[1, 1], np.ones_like(u, float)],
        -1,
    )
    n = T_cam_target[:3, 2]
    p0 = T_cam_target[:3, 3]
    denom = rays @ n
    with np.errstate(divide="ignore", invalid="ignore"):
        z = (p0 @ n) / denom
    return np.where(z > 0, z, np.nan)


def look_at_target(
    target_in_cam_xyz: npt.ArrayLike, rpy: npt.ArrayLike, viewed_from_z: float
) -> Array:
    """``T_cam_target`` with the target's origin at ``target_in_cam_xyz`` (m), facing the
    camera from the side its texture is read on, then turned by ``rpy`` (rad)."""
    # A target whose readable side is +z faces the camera when its z points to -z_cam and
    # y up (-y_cam); for the boards (read from -z), z along +z_cam and y down (+y_cam).
    R0 = np.diag([1.0, -1.0, -1.0]) if viewed_from_z > 0 else np.eye(3)
    T = make_transform(R0, np.asarray(target_in_cam_xyz, float))
    return T @ from_xyz_rpy([0, 0, 0], rpy)
