"""Camera pose of a target from one detection, and a robust average over frames.

Frames: ``T_cam_target`` is the target frame (see ``calibration.targets``) in the camera's
optical frame (OpenCV: x right, y down, z forward), metres.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from calibration.detect import Detection
from calibration.targets import SingleTag, Target
from gaide_core.errors import CalibrationError
from gaide_core.transforms import apply, make_transform, rotation_angle
from gaide_core.types import Array

log = logging.getLogger(__name__)


#: A single tag's pose is reported ambiguous (a warning is logged) when the reprojection
#: RMS of the better of SOLVEPNP_IPPE_SQUARE's two solutions is above this share of the
#: other's. Why 0.5: simulated 8 cm tags (0.2-4 m, 0-60 degrees tilt, 0.05-0.4 px corner
#: noise, 20000 poses) kept a pose more than 10 degrees off, i.e. the mirrored solution, in
#: 0.4 % of frames below a ratio of 0.1, 6 % at 0.2-0.3, 15 % at 0.4-0.5, 23 % at 0.5-0.6
#: and 30-46 % above 0.6: from 0.5 on, at least one frame in five has the wrong one.
AMBIGUITY_WARN = 0.5


@dataclass(frozen=True, eq=False)
class FramePose:
    """``T_cam_target`` (4, 4) of one frame and its reprojection RMS (px) over its points.

    ``ambiguity``: for a single tag, the reprojection RMS of the pose kept over that of the
    other of its two (mirrored) solutions, in [0, 1]: near 0 the pose is clear, near 1 the
    two explain the corners equally well and the pose may flip between frames (small, far,
    face-on tags); None for boards, whose points fix the pose.
    """

    T_cam_target: Array
    rms_px: float
    ambiguity: float | None = None


def dist_coeffs(D: Array | None) -> Array:
    """OpenCV distortion coefficients as a flat float64 array (zeros for None)."""
    return np.zeros(5) if D is None else np.asarray(D, np.float64).ravel()


def project(K: Array, D: Array | None, T_cam_target: Array, points: Array) -> Array:
    """(N, 2) pixels of (N, 3) target-frame points (m) seen at ``T_cam_target``."""
    rvec = cv2.Rodrigues(np.ascontiguousarray(T_cam_target[:3, :3]))[0]
    uv, _ = cv2.projectPoints(
        np.ascontiguousarray(points, np.float64), rvec, T_cam_target[:3, 3], K, dist_coeffs(D)
    )
    return np.asarray(uv, np.float64).reshape(-1, 2)


def reprojection_rms(K: Array, D: Array | None, T_cam_target: Array, det: Detection) -> float:
    """RMS (px) of the distance between detected and projected points."""
    err = project(K, D, T_cam_target, det.object_points) - det.image_points
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1))))


def solve_pose(det: Detection, target: Target, K: Array, D: Array | None = None) -> FramePose:
    """``T_cam_target`` of one detection.

    A single tag uses ``SOLVEPNP_IPPE_SQUARE``: both its solutions are polished by
    Levenberg-Marquardt and the one with the lower reprojection error kept; their error ratio
    is the pose's ``ambiguity``, and above ``AMBIGUITY_WARN`` a warning names how far apart
    the two are. Boards use ``SOLVEPNP_SQPNP``, a global solver that needs no initial guess,
    then Levenberg-Marquardt.
    """
    if not det.found:
        raise CalibrationError(f"no pose without a detection of {target.describe()}")
    obj = np.ascontiguousarray(det.object_points, np.float64)
    img = np.ascontiguousarray(det.image_points, np.float64)
    dist = dist_coeffs(D)
    ambiguity = None
    try:
        if isinstance(target, SingleTag) and len(obj) == 4:
            n, rvecs, tvecs, _ = cv2.solvePnPGeneric(
                obj, img, K, dist, flags=cv2.SOLVEPNP_IPPE_SQUARE
            )
            if n == 0:
                raise CalibrationError(f"PnP found no pose for {target.describe()}")
            poses = [
                _pose(*cv2.solvePnPRefineLM(obj, img, K, dist, r, t))
                for r, t in zip(rvecs[:n], tvecs[:n], strict=True)
            ]
            ranked = sorted(poses, key=lambda T: reprojection_rms(K, D, T, det))
            T = ranked[0]
            if len(ranked) > 1:
                ambiguity = _ambiguity(K, D, det, target, T, ranked[1])
        else:
            ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_SQPNP)
            if not ok:
                raise CalibrationError(f"PnP found no pose for {target.describe()}")
            T = _pose(*cv2.solvePnPRefineLM(obj, img, K, dist, rvec, tvec))
    except cv2.error as err:
        raise CalibrationError(f"PnP failed for {target.describe()}: {err}") from err
    if np.any(apply(T, obj)[:, 2] <= 0):
        raise CalibrationError(
            f"PnP put {target.describe()} behind the camera: check the camera matrix K"
        )
    return FramePose(T, reprojection_rms(K, D, T, det), ambiguity)


def _pose(rvec: Any, tvec: Any) -> Array:
    """(4, 4) pose from OpenCV's rotation vector and translation."""
    return make_transform(np.asarray(cv2.Rodrigues(rvec)[0], np.float64), np.ravel(tvec))


def _ambiguity(
    K: Array, D: Array | None, det: Detection, target: Target, best: Array, other: Array
) -> float:
    """Reprojection RMS ratio of the ``best`` and ``other`` single-tag poses; logs a warning
    above ``AMBIGUITY_WARN``."""
    e_best = reprojection_rms(K, D, best, det)
    e_other = reprojection_rms(K, D, other, det)
    ratio = 1.0 if e_other <= 0 else min(e_best / e_other, 1.0)
    if ratio > AMBIGUITY_WARN:
        apart = np.degrees(rotation_angle(best[:3, :3].T @ other[:3, :3]))
        log.warning(
            "%s: ambiguous pose, its two solutions %.1f deg apart fit the corners almost "
            "equally (reprojection RMS %.3f vs %.3f px, ratio %.2f > %.2f): it may flip "
            "between frames; bring the tag closer or tilt it away from face-on, or use a board",
            target.describe(),
            apart,
            e_best,
            e_other,
            ratio,
            AMBIGUITY_WARN,
        )
    return ratio


@dataclass(frozen=True, eq=False)
class PoseAverage:
    """Robust mean of poses: ``T`` (4, 4), the indices ``used``, and ``rejected`` as
    (index, reason) pairs."""

    T: Array
    used: tuple[int, ...]
    rejected: tuple[tuple[int, str], ...]


#: Deviations smaller than these are within detection noise and never make a frame an
#: outlier, even when the median absolute deviation is tiny (e.g. near-identical frames).
MIN_OUTLIER_M = 0.002
MIN_OUTLIER_RAD = np.radians(0.2)


def robust_average(poses: Sequence[Array], *, k: float = 5.0) -> PoseAverage:
    """Rotation mean (chordal, ``Rotation.mean``) and translation median of (4, 4) poses,
    after rejecting outlier frames.

    A frame is an outlier when its distance from the median translation, or its rotation
    angle from the robust mean rotation, exceeds ``k`` x 1.4826 x the median of those
    deviations over all frames (the median absolute deviation, MAD), and also exceeds
    ``MIN_OUTLIER_M`` / ``MIN_OUTLIER_RAD``. Why the MAD: unlike the standard deviation, which
    one bad frame inflates until it hides itself, the median ignores up to half the frames
    being wrong. For 3-D Gaussian noise the median distance is about 1.5 sigma per axis, so
    k = 5 puts the limit near 11 sigma: honest frames never cross it, while a misdetection
    or a flipped single-tag solution (degrees, centimetres) does.
    """
    if not poses:
        raise CalibrationError("no poses to average")
    Ts = np.asarray(poses, np.float64).reshape(-1, 4, 4)
    rots = Rotation.from_matrix(Ts[:, :3, :3])
    t_med = np.median(Ts[:, :3, 3], axis=0)
    r_med = rots.mean()
    for _ in range(2):  # re-centre on the closer half: the chordal mean is not robust
        ang = (r_med.inv() * rots).magnitude()
        r_med = rots[ang <= np.median(ang)].mean()
    dt = np.linalg.norm(Ts[:, :3, 3] - t_med, axis=1)
    dr = (r_med.inv() * rots).magnitude()
    lim_t = max(k * 1.4826 * float(np.median(dt)), MIN_OUTLIER_M)
    lim_r = max(k * 1.4826 * float(np.median(dr)), MIN_OUTLIER_RAD)
    used, rejected = [], []
    for i in range(len(Ts)):
        if dt[i] > lim_t:
            rejected.append(
                (i, f"position {dt[i] * 1e3:.1f} mm from the median (limit {lim_t * 1e3:.1f} mm)")
            )
        elif dr[i] > lim_r:
            rejected.append(
                (
                    i,
                    f"rotation {np.degrees(dr[i]):.2f} deg from the mean (limit {np.degrees(lim_r):.2f} deg)",
                )
            )
        else:
            used.append(i)
    if not used:
        raise CalibrationError(
            f"no consistent poses among {len(Ts)} frames: every one is an outlier ({rejected})"
        )
    if rejected:
        log.info("pose average: %d of %d frames rejected: %s", len(rejected), len(Ts), rejected)
    T = make_transform(rots[used].mean().as_matrix(), np.median(Ts[used, :3, 3], axis=0))
    return PoseAverage(T, tuple(used), tuple(rejected))


def pose_difference(T_a: Array, T_b: Array) -> tuple[float, float]:
    """Translation difference (m) and rotation difference (rad) of two (4, 4) poses."""
    return (
        float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])),
        rotation_angle(T_a[:3, :3].T @ T_b[:3, :3]),
    )
