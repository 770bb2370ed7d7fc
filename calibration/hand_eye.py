"""Eye-to-hand calibration: the camera is fixed, the target rides on the robot's flange.

Unknowns: ``X = T_base_cam`` and ``Y = T_flange_target``. Frame i gives
``T_base_flange_i @ Y = X @ T_cam_target_i``.

``cv2.calibrateHandEye`` solves the eye-in-hand form ``T_base_gripper_i @ T_gripper_cam @
T_cam_target_i = const``. Fed ``inv(T_base_flange_i)`` as the "gripper to base" poses, its
equation reads ``T_flange_base_i @ X @ T_cam_target_i = const = Y``, the eye-to-hand
equation, and its "camera to gripper" answer is ``X = T_base_cam``. Five closed-form methods
are run and reported; the one with the lowest reprojection error starts a least-squares
refinement of X and Y on the reprojection error of every target point in every frame.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Sequence

import cv2
import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from calibration.detect import Detection
from calibration.frames import check_camera, check_stamps, not_found_error, observe
from calibration.pnp import dist_coeffs, pose_difference, robust_average
from calibration.result import (
    CalibrationResult,
    FrameResidual,
    MethodResult,
    Mode,
    Spread,
    camera_fields,
)
from calibration.scale_check import check_target_scale
from calibration.targets import Target, to_dict
from gaide_core.camera import Intrinsics
from gaide_core.errors import CalibrationError
from gaide_core.transforms import invert, is_rigid, make_transform
from gaide_core.types import Array

log = logging.getLogger(__name__)

METHODS = {
    "tsai": cv2.CALIB_HAND_EYE_TSAI,
    "park": cv2.CALIB_HAND_EYE_PARK,
    "horaud": cv2.CALIB_HAND_EYE_HORAUD,
    "andreff": cv2.CALIB_HAND_EYE_ANDREFF,
    "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS,
}
#: Flange poses closer than this (m, deg) count as the same pose.
SAME_POSE_M, SAME_POSE_DEG = 0.001, 0.5
#: Relative rotations smaller than this (deg) carry no axis information.
MIN_ROTATION_DEG = 5.0
#: Rotation axes all within this angle (deg) of one line: motion about one axis only.
MIN_AXIS_SPREAD_DEG = 5.0
#: Frames whose RMS (px) after refinement exceeds ``OUTLIER_K`` robust sigmas above the
#: median, and ``OUTLIER_MIN_PX``, are dropped and the refinement is run again.
OUTLIER_K, OUTLIER_MIN_PX = 5.0, 1.0


def _distinct_poses(poses: Sequence[Array]) -> list[int]:
    """Indices of the poses that differ from every earlier kept one."""
    keep: list[int] = []
    for i, T in enumerate(poses):
        diffs = [pose_difference(T, poses[j]) for j in keep]
        if all(t > SAME_POSE_M or np.degrees(r) > SAME_POSE_DEG for t, r in diffs):
            keep.append(i)
    return keep


def check_motion(T_base_flange: Sequence[Array]) -> None:
    """Refuse flange motions that do not determine the hand-eye transform.

    Needs 3 distinct poses, relative rotations of at least ``MIN_ROTATION_DEG``, and
    rotation axes (of the relative motions, in the flange frame) that are not all parallel:
    with one axis, the offset along it cannot be observed.
    """
    distinct = _distinct_poses(T_base_flange)
    if len(distinct) < 3:
        raise CalibrationError(
            f"{len(distinct)} distinct flange poses in {len(T_base_flange)} frames: hand-eye "
            "calibration needs at least 3, better 10 or more, turned about several axes"
        )
    axes, largest = [], 0.0
    for i, j in itertools.combinations(distinct, 2):
        rel = Rotation.from_matrix(T_base_flange[i][:3, :3].T @ T_base_flange[j][:3, :3])
        angle = np.degrees(rel.magnitude())
        largest = max(largest, angle)
        if angle >= MIN_ROTATION_DEG:
            axes.append(rel.as_rotvec() / np.radians(angle))
    if not axes:
        raise CalibrationError(
            f"too little rotation: the flange turns at most {largest:.1f} deg between poses; "
            f"turn it by {MIN_ROTATION_DEG:.0f} deg or more (ideally 30+) about several axes"
        )
    A = np.array(axes)
    principal = np.linalg.svd(A)[2][0]
    off_axis = np.degrees(np.arccos(np.clip(np.abs(A @ principal), 0.0, 1.0)))
    if off_axis.max() < MIN_AXIS_SPREAD_DEG:
        raise CalibrationError(
            "degenerate motion: every relative rotation of the flange is about one axis "
            f"(within {off_axis.max():.1f} deg of {np.round(principal, 3).tolist()} in the "
            "flange frame), so the offset along that axis is unobservable; rotate the flange "
            "about at least two different axes"
        )


def _pose_vec(T: Array) -> Array:
    return np.concatenate([Rotation.from_matrix(T[:3, :3]).as_rotvec(), T[:3, 3]])


def _vec_pose(v: Array) -> Array:
    return make_transform(Rotation.from_rotvec(v[:3]).as_matrix(), v[3:6])


def _residuals(
    params: Array, cam: Intrinsics, T_flange_base: Array, dets: Sequence[Detection]
) -> Array:
    """Pixel residuals (2 per point, all frames) for params = [X (6), Y (6)] as rotvec + t."""
    X, Y = _vec_pose(params[:6]), _vec_pose(params[6:])
    X_inv = invert(X)
    out = []
    for T_fb, det in zip(T_flange_base, dets, strict=True):
        T_cam_target = X_inv @ invert(T_fb) @ Y
        rvec = Rotation.from_matrix(T_cam_target[:3, :3]).as_rotvec()
        uv, _ = cv2.projectPoints(
            det.object_points, rvec, T_cam_target[:3, 3], cam.K, dist_coeffs(cam.D)
        )
        out.append((uv.reshape(-1, 2) - det.image_points).ravel())
    return np.concatenate(out)


def _frame_rms(res: Array, dets: Sequence[Detection]) -> Array:
    """Per-frame RMS (px) of point distances, from the stacked residuals."""
    rms, start = [], 0
    for det in dets:
        n = 2 * len(det.object_points)
        rms.append(np.sqrt(np.mean(res[start : start + n] ** 2) * 2))
        start += n
    return np.array(rms)


def _flange_target(X: Array, T_flange_base: Array, T_cam_target: Sequence[Array]) -> Array:
    """Y given X: the robust average of ``inv(T_base_flange_i) @ X @ T_cam_target_i``."""
    Ys = [T_fb @ X @ T_ct for T_fb, T_ct in zip(T_flange_base, T_cam_target, strict=True)]
    return robust_average(Ys).T


def _refine(
    X0: Array, Y0: Array, cam: Intrinsics, T_flange_base: Array, dets: Sequence[Detection]
) -> tuple[Array, Array, Array]:
    """Least-squares X, Y (robust soft-L1 loss, 1 px scale) and the final residuals."""
    sol = least_squares(
        _residuals,
        np.concatenate([_pose_vec(X0), _pose_vec(Y0)]),
        args=(cam, T_flange_base, dets),
        loss="soft_l1",
        f_scale=1.0,
        x_scale="jac",
    )
    return _vec_pose(sol.x[:6]), _vec_pose(sol.x[6:]), np.asarray(sol.fun)


def _spread(results: Sequence[MethodResult]) -> Spread:
    dt, dr = 0.0, 0.0
    for a, b in itertools.combinations(results, 2):
        t, r = pose_difference(a.T_base_cam, b.T_base_cam)
        dt, dr = max(dt, t), max(dr, r)
    return Spread(translation_mm=dt * 1e3, rotation_deg=float(np.degrees(dr)))


def calibrate_hand_eye(
    images: Sequence[npt.NDArray[np.uint8]],
    K: Array,
    D: Array | None,
    target: Target,
    T_base_flange: Sequence[Array],
    *,
    stamps_ns: Sequence[int] | None = None,
    depth_m: Sequence[Array] | None = None,
    min_detected_fraction: float = 0.5,
) -> CalibrationResult:
    """Eye-to-hand ``T_base_cam`` from images of a target fixed to the flange.

    ``images``: gray or RGB uint8 from the fixed camera; ``K`` (3, 3) px, ``D`` (OpenCV
    distortion, or None); ``T_base_flange``: (4, 4) flange pose in the base frame (m) when
    each image was taken (from the caller's forward kinematics); ``stamps_ns``: per-image
    stamps (ns); ``depth_m``: per-image depth (m) aligned to the color image, to catch a
    wrong target size. The result also holds ``T_flange_target``, each closed-form method's
    ``T_base_cam`` and their spread. Raises ``CalibrationError`` for fewer than 3 distinct
    poses, degenerate motion, or a target found in under ``min_detected_fraction`` of images.
    """
    cam = check_camera(images, K, D)
    if len(T_base_flange) != len(images):
        raise CalibrationError(
            f"{len(T_base_flange)} flange poses for {len(images)} images: give one per image"
        )
    flange = [np.asarray(T, np.float64) for T in T_base_flange]
    for i, T in enumerate(flange):
        if not is_rigid(T, tol=1e-5):
            raise CalibrationError(f"flange pose {i} is not a rigid 4x4 transform:\n{T}")
    check_motion(flange)  # before the slow part; checked again on the frames that see the target
    obs_all = observe(images, cam, target, check_stamps(stamps_ns, len(images)))
    obs = [o for o in obs_all if o.pose is not None]
    if len(obs) < max(3, min_detected_fraction * len(images)):
        raise not_found_error(
            target, obs_all, f"need at least 3 and {min_detected_fraction:.0%} of the images"
        )
    if depth_m is not None:
        check_target_scale(
            [o.detection for o in obs_all],
            [None if o.pose is None else o.pose.T_cam_target for o in obs_all],
            depth_m,
            target,
        )
    T_bf = np.array([flange[o.index] for o in obs])
    check_motion(list(T_bf))
    T_fb = np.array([invert(T) for T in T_bf])
    T_ct = [o.pose.T_cam_target for o in obs if o.pose is not None]
    dets = [o.detection for o in obs if o.detection is not None]

    methods: list[MethodResult] = []
    starts: dict[str, tuple[Array, Array]] = {}
    for name, flag in METHODS.items():
        try:
            R, t = cv2.calibrateHandEye(
                [T[:3, :3] for T in T_fb],
                [T[:3, 3] for T in T_fb],
                [T[:3, :3] for T in T_ct],
                [T[:3, 3] for T in T_ct],
                method=flag,
            )
        except cv2.error as err:
            log.warning("hand-eye method %s failed: %s", name, err)
            continue
        R = np.asarray(R, np.float64)
        if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t)) and np.linalg.det(R) > 0.5):
            log.warning("hand-eye method %s gave no rotation (det %.2f)", name, np.linalg.det(R))
            continue
        # Re-orthonormalise: some methods return a rotation that is a little off.
        X = make_transform(Rotation.from_matrix(R).as_matrix(), np.ravel(t))
        Y = _flange_target(X, T_fb, T_ct)
        res = _residuals(np.concatenate([_pose_vec(X), _pose_vec(Y)]), cam, T_fb, dets)
        method_rms = float(np.sqrt(np.mean(res**2) * 2))
        methods.append(MethodResult(name, X, method_rms))
        starts[name] = (X, Y)
        log.info("hand-eye %s: reprojection RMS %.3f px", name, method_rms)
    if not methods:
        raise CalibrationError("every hand-eye method failed: check the flange poses and images")
    best = min(methods, key=lambda m: m.rms_px)
    spread = _spread(methods)
    log.info(
        "hand-eye methods agree within %.2f mm / %.3f deg; refining from %s",
        spread.translation_mm,
        spread.rotation_deg,
        best.name,
    )

    X, Y, res = _refine(*starts[best.name], cam, T_fb, dets)
    rms = _frame_rms(res, dets)
    med = float(np.median(rms))
    limit = max(med + OUTLIER_K * 1.4826 * float(np.median(np.abs(rms - med))), OUTLIER_MIN_PX)
    keep = [k for k in range(len(obs)) if rms[k] <= limit]
    rejected: dict[int, str] = {}
    if len(keep) < len(obs) and len(keep) >= 3:
        for k in set(range(len(obs))) - set(keep):
            rejected[obs[k].index] = f"{rms[k]:.2f} px after refinement (limit {limit:.2f} px)"
        X, Y, _ = _refine(X, Y, cam, T_fb[keep], [dets[k] for k in keep])
    res = _residuals(np.concatenate([_pose_vec(X), _pose_vec(Y)]), cam, T_fb, dets)
    rms = _frame_rms(res, dets)
    by_index = {o.index: float(r) for o, r in zip(obs, rms, strict=True)}
    frames = tuple(
        FrameResidual(
            o.index,
            o.stamp_ns,
            by_index.get(o.index),
            o.index in by_index and o.index not in rejected,
            rejected.get(o.index, o.reason),
        )
        for o in obs_all
    )
    used_sq = [r**2 for o, r in zip(obs, rms, strict=True) if o.index not in rejected]
    pts = [len(d.object_points) for o, d in zip(obs, dets, strict=True) if o.index not in rejected]
    rms_all = float(np.sqrt(np.dot(used_sq, pts) / np.sum(pts)))
    log.info("hand-eye refined: reprojection RMS %.3f px over %d frames", rms_all, len(pts))
    if rms_all > 2.0:
        log.warning(
            "hand-eye reprojection RMS %.2f px is high: check the flange poses' time alignment, "
            "the intrinsics and the target size",
            rms_all,
        )
    return CalibrationResult(
        mode=Mode.HAND_EYE,
        T_base_cam=X,
        **camera_fields(cam),
        reprojection_rms_px=rms_all,
        frames=frames,
        methods=tuple(methods),
        spread=spread,
        T_flange_target=Y,
        target=to_dict(target),
    )
