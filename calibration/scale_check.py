"""Catching a wrong target size with a depth image.

PnP with a target size s puts the target at a distance proportional to s, so a wrong size
gives a wrong distance (and a wrong ``T_base_cam``) with a perfect reprojection error: only
an independent range measurement can tell. A depth image aligned to the color image gives
it: the ratio of measured depth to the PnP depth of the target's points is the factor by
which the size is off.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from calibration.detect import Detection
from calibration.targets import Target
from gaide_core.errors import CalibrationError
from gaide_core.transforms import apply
from gaide_core.types import Array

log = logging.getLogger(__name__)

#: Half-width (px) of the window whose valid depths are pooled (median) at each point.
WINDOW = 2
#: Fewest points with depth needed to judge the size.
MIN_POINTS = 4


def depth_pairs(det: Detection, T_cam_target: Array, depth_m: Array) -> tuple[Array, Array]:
    """(PnP depth, measured depth) (m, along the optical axis) of the detected points that
    have depth data; ``depth_m`` (H, W) metres, 0 or NaN where there is none."""
    depth = np.asarray(depth_m, np.float64)
    if depth.ndim != 2:
        raise CalibrationError(f"a depth image must be (H, W) metres, got shape {depth.shape}")
    h, w = depth.shape
    z_pnp = apply(T_cam_target, det.object_points)[:, 2]
    pnp, measured = [], []
    for (u, v), z in zip(det.image_points, z_pnp, strict=True):
        c, r = round(u), round(v)
        if not (0 <= c < w and 0 <= r < h):
            continue
        patch = depth[max(r - WINDOW, 0) : r + WINDOW + 1, max(c - WINDOW, 0) : c + WINDOW + 1]
        valid = patch[np.isfinite(patch) & (patch > 0)]
        if valid.size:
            pnp.append(z)
            measured.append(float(np.median(valid)))
    return np.array(pnp), np.array(measured)


def check_target_scale(
    detections: Sequence[Detection | None],
    poses: Sequence[Array | None],
    depths_m: Sequence[Array],
    target: Target,
    *,
    tolerance: float = 0.10,
) -> float | None:
    """Compare PnP distances with depth over all frames; raise ``CalibrationError`` naming
    the size that would agree when they differ by more than ``tolerance`` (relative).

    ``detections``/``poses`` (``T_cam_target``, (4, 4)) per frame, None where the target was
    not found; ``depths_m`` per frame, (H, W) metres aligned to the color image. Returns the
    median ratio depth / PnP, or None when too few points have depth (the check is skipped).
    """
    if len(depths_m) != len(detections):
        raise CalibrationError(
            f"{len(depths_m)} depth images for {len(detections)} color images: give one per image"
        )
    pnp_all, measured_all = [], []
    for det, T, depth in zip(detections, poses, depths_m, strict=True):
        if det is None or T is None:
            continue
        pnp, measured = depth_pairs(det, T, depth)
        pnp_all.append(pnp)
        measured_all.append(measured)
    pnp_z = np.concatenate(pnp_all) if pnp_all else np.zeros(0)
    depth_z = np.concatenate(measured_all) if measured_all else np.zeros(0)
    if len(pnp_z) < MIN_POINTS:
        log.warning(
            "size check skipped: only %d target points have depth (need %d)",
            len(pnp_z),
            MIN_POINTS,
        )
        return None
    ratio = float(np.median(depth_z / pnp_z))
    log.info("size check: depth / PnP distance = %.3f over %d points", ratio, len(pnp_z))
    if abs(ratio - 1.0) > tolerance:
        raise CalibrationError(
            f"{target.size_text()} puts it at {np.median(pnp_z):.2f} m but depth says "
            f"{np.median(depth_z):.2f} m: is the {target.scaled(ratio).size_text()}? "
            f"(sizes within {tolerance:.0%} of depth are accepted)"
        )
    return ratio
