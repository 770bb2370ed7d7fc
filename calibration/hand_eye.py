"""Hand-eye calibration, both set-ups.

- Eye-to-hand (``Setup.EYE_TO_HAND``): the camera is fixed, the target rides on the flange.
  Unknowns ``X = T_base_cam`` and ``Y = T_flange_target``; frame i gives
  ``T_base_flange_i @ Y = X @ T_cam_target_i``.
- Eye-in-hand (``Setup.EYE_IN_HAND``): the camera rides on the flange, the target is fixed.
  Unknowns ``X = T_flange_cam`` and ``Y = T_base_target``; frame i gives
  ``T_base_flange_i @ X @ T_cam_target_i = Y``.

Both read ``T_cam_target_i = inv(X) @ A_i @ Y`` with ``A_i = T_base_flange_i`` (eye-to-hand)
or ``inv(T_base_flange_i)`` (eye-in-hand). ``cv2.calibrateHandEye`` solves
``T_base_gripper_i @ T_gripper_cam @ T_cam_target_i = const``: fed ``inv(A_i)`` as the
"gripper to base" poses its answer is X in either set-up. Five closed-form methods are run
and reported; the one with the lowest reprojection error starts a least-squares refinement
of X and Y together on the reprojection error of every target point in every frame. The
refined estimate's standard deviation comes from that least-squares problem (Gauss-Newton
covariance, scaled by the residuals' variance), so a user learns how well the data pins the
answer down rather than how much the closed-form methods disagree.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable, Sequence

import cv2
import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from calibration.detect import Detection
from calibration.frames import Observation, check_camera, check_stamps, not_found_error, observe
from calibration.pnp import dist_coeffs, pose_difference, robust_average
from calibration.result import (
    CalibrationResult,
    FrameResidual,
    MethodResult,
    Mode,
    Setup,
    Spread,
    Uncertainty,
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


def _residuals(params: Array, cam: Intrinsics, A: Array, dets: Sequence[Detection]) -> Array:
    """Pixel residuals (2 per point, all frames) for params = [X (6), Y (6)] as rotvec + t,
    with ``T_cam_target_i = inv(X) @ A_i @ Y`` (see the module docstring)."""
    return _pose_residuals(_vec_pose(params[:6]), _vec_pose(params[6:]), cam, A, dets)


def _pose_residuals(
    X: Array, Y: Array, cam: Intrinsics, A: Array, dets: Sequence[Detection]
) -> Array:
    X_inv = invert(X)
    out = []
    for A_i, det in zip(A, dets, strict=True):
        T_cam_target = X_inv @ A_i @ Y
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


def _other_unknown(X: Array, A_inv: Array, T_cam_target: Sequence[Array]) -> Array:
    """Y given X: the robust average of ``inv(A_i) @ X @ T_cam_target_i``."""
    Ys = [B @ X @ T_ct for B, T_ct in zip(A_inv, T_cam_target, strict=True)]
    return robust_average(Ys).T


def _refine(
    X0: Array, Y0: Array, cam: Intrinsics, A: Array, dets: Sequence[Detection]
) -> tuple[Array, Array, Array]:
    """Least-squares X, Y (robust soft-L1 loss, 1 px scale) and the final residuals."""
    sol = least_squares(
        _residuals,
        np.concatenate([_pose_vec(X0), _pose_vec(Y0)]),
        args=(cam, A, dets),
        loss="soft_l1",
        f_scale=1.0,
        x_scale="jac",
    )
    return _vec_pose(sol.x[:6]), _vec_pose(sol.x[6:]), np.asarray(sol.fun)


def _perturbed(T: Array, d: Array) -> Array:
    """``T`` moved by ``d`` = [rotation vector (3, rad), translation (3, m)], both in the
    frame ``T`` is expressed in (the parent frame), so ``d`` reads as the error of T."""
    return make_transform(Rotation.from_rotvec(d[:3]).as_matrix() @ T[:3, :3], T[:3, 3] + d[3:])


def uncertainty(
    X: Array, Y: Array, cam: Intrinsics, A: Array, dets: Sequence[Detection]
) -> Uncertainty:
    """Standard deviation of X from the least-squares problem at the solution (X, Y).

    Local parameters: a rotation vector and a translation applied to X (and Y) in their
    parent frame. Covariance ``s^2 (J^T J)^-1`` with J the residuals' Jacobian (central
    differences; 12 parameters, cheap) and ``s^2`` the residuals' variance per degree of
    freedom. Y is a nuisance parameter: its correlation with X is kept (the full inverse).
    """
    r0 = _pose_residuals(X, Y, cam, A, dets)
    steps = np.array([1e-6] * 3 + [1e-6] * 3)
    cols = []
    for k in range(12):
        d = np.zeros(12)
        d[k] = steps[k % 6]
        plus = _pose_residuals(_perturbed(X, d[:6]), _perturbed(Y, d[6:]), cam, A, dets)
        minus = _pose_residuals(_perturbed(X, -d[:6]), _perturbed(Y, -d[6:]), cam, A, dets)
        cols.append((plus - minus) / (2 * steps[k % 6]))
    J = np.column_stack(cols)
    dof = max(len(r0) - 12, 1)
    s2 = float(r0 @ r0) / dof
    cov = s2 * np.linalg.pinv(J.T @ J)
    rot_axes = np.sqrt(np.clip(np.diag(cov)[:3], 0, None))
    t_axes = np.sqrt(np.clip(np.diag(cov)[3:6], 0, None))
    return Uncertainty(
        translation_mm=float(np.linalg.norm(t_axes)) * 1e3,
        rotation_deg=float(np.degrees(np.linalg.norm(rot_axes))),
        translation_axes_mm=tuple(float(v) * 1e3 for v in t_axes),
        rotation_axes_deg=tuple(float(np.degrees(v)) for v in rot_axes),
    )


def rms_limit_px(width: int, height: int) -> float:
    """Reprojection RMS (px) above which a result deserves a look: 0.15% of the image
    diagonal, at least 1 px (1.2 px at 640x480, 4.8 px at 2448x2048). Detection noise grows
    with resolution and blur, so a fixed pixel figure alarms users of large sensors."""
    return max(1.0, 0.0015 * float(np.hypot(width, height)))


#: Standard deviations of the answer above which a warning says the data is weak.
WARN_STD_MM, WARN_STD_DEG = 2.0, 0.2


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
    setup: Setup | str = Setup.EYE_TO_HAND,
    stamps_ns: Sequence[int] | None = None,
    depth_m: Sequence[Array] | None = None,
    min_detected_fraction: float = 0.5,
) -> CalibrationResult:
    """Hand-eye calibration from images and the flange pose at each image.

    ``setup``: ``eye-to-hand`` (fixed camera, target on the flange; gives ``T_base_cam`` and
    ``T_flange_target``) or ``eye-in-hand`` (camera on the flange, target fixed; gives
    ``T_flange_cam`` and ``T_base_target``, and ``T_base_cam`` and the methods' answers are
    the camera at the first image that shows the target). ``images``: gray or RGB uint8; ``K`` (3, 3) px, ``D`` (OpenCV distortion,
    or None); ``T_base_flange``: (4, 4) flange pose in the base frame (m) at each image;
    ``stamps_ns``: per-image stamps (ns); ``depth_m``: per-image depth (m) aligned to the
    color image, to catch a wrong target size. The result also holds each closed-form
    method's answer, their spread, and the refined answer's standard deviation. Raises
    ``CalibrationError`` for counts that differ, fewer than 3 distinct poses, degenerate
    motion, or a target found in under ``min_detected_fraction`` of the images.
    """
    setup = Setup.parse(setup)
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
            target,
            obs_all,
            f"need at least 3 and {min_detected_fraction:.0%} of the images",
            images,
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
    # T_cam_target_i = inv(X) @ A_i @ Y; calibrateHandEye takes inv(A_i) as gripper-to-base.
    A, A_inv = (T_bf, T_fb) if setup is Setup.EYE_TO_HAND else (T_fb, T_bf)
    first = obs[0].index

    def camera_in_base(X: Array) -> Array:
        """T_base_cam from X: X itself, or eye-in-hand the camera at the first detection."""
        return X if setup is Setup.EYE_TO_HAND else flange[first] @ X

    T_ct = [o.pose.T_cam_target for o in obs if o.pose is not None]
    dets = [o.detection for o in obs if o.detection is not None]

    methods, starts = _closed_form(A, A_inv, T_ct, cam, dets, camera_in_base)
    best = min(methods, key=lambda m: m.rms_px)
    spread = _spread(methods)
    log.info(
        "closed-form hand-eye methods agree within %.2f mm / %.3f deg (a start only); "
        "refining from %s",
        spread.translation_mm,
        spread.rotation_deg,
        best.name,
    )

    X, Y, rejected = _refine_without_outliers(*starts[best.name], cam, A, dets, obs)
    res = _pose_residuals(X, Y, cam, A, dets)
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
    used = [k for k, o in enumerate(obs) if o.index not in rejected]
    pts = [len(dets[k].object_points) for k in used]
    rms_all = float(np.sqrt(np.dot([rms[k] ** 2 for k in used], pts) / np.sum(pts)))
    std = uncertainty(X, Y, cam, A[used], [dets[k] for k in used])
    log.info(
        "hand-eye (%s) refined: reprojection RMS %.3f px over %d frames; standard deviation "
        "%.2f mm, %.3f deg",
        setup.value,
        rms_all,
        len(pts),
        std.translation_mm,
        std.rotation_deg,
    )
    _warn_if_weak(rms_all, std, cam)
    in_hand = setup is Setup.EYE_IN_HAND
    return CalibrationResult(
        mode=Mode.HAND_EYE,
        setup=setup,
        T_base_cam=camera_in_base(X),
        **camera_fields(cam),
        reprojection_rms_px=rms_all,
        frames=frames,
        methods=tuple(methods),
        spread=spread,
        uncertainty=std,
        T_flange_target=None if in_hand else Y,
        T_flange_cam=X if in_hand else None,
        T_base_target=Y if in_hand else None,
        target=to_dict(target),
    )


def _closed_form(
    A: Array,
    A_inv: Array,
    T_ct: Sequence[Array],
    cam: Intrinsics,
    dets: Sequence[Detection],
    camera_in_base: Callable[[Array], Array],
) -> tuple[list[MethodResult], dict[str, tuple[Array, Array]]]:
    """OpenCV's closed-form hand-eye methods (``METHODS``): each one's answer as the camera in
    the base frame with its reprojection RMS, and its (X, Y) to start a refinement from. A
    method that fails or gives no rotation is left out with a warning; CalibrationError when
    all do."""
    methods: list[MethodResult] = []
    starts: dict[str, tuple[Array, Array]] = {}
    for name, flag in METHODS.items():
        try:
            R, t = cv2.calibrateHandEye(
                [T[:3, :3] for T in A_inv],
                [T[:3, 3] for T in A_inv],
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
        Y = _other_unknown(X, A_inv, T_ct)
        res = _pose_residuals(X, Y, cam, A, dets)
        method_rms = float(np.sqrt(np.mean(res**2) * 2))
        methods.append(MethodResult(name, camera_in_base(X), method_rms))
        starts[name] = (X, Y)
        log.info("hand-eye %s: reprojection RMS %.3f px", name, method_rms)
    if not methods:
        raise CalibrationError("every hand-eye method failed: check the flange poses and images")
    return methods, starts


def _refine_without_outliers(
    X: Array,
    Y: Array,
    cam: Intrinsics,
    A: Array,
    dets: Sequence[Detection],
    obs: Sequence[Observation],
) -> tuple[Array, Array, dict[int, str]]:
    """Refine (X, Y) on every frame, then again without the frames whose reprojection RMS is
    ``OUTLIER_K`` robust sigmas above the median (at least ``OUTLIER_MIN_PX``), as long as 3
    frames stay. Returns the refined (X, Y) and the reason each dropped frame was dropped,
    by image index (``obs[k].index`` for frame k)."""
    X, Y, res = _refine(X, Y, cam, A, dets)
    rms = _frame_rms(res, dets)
    med = float(np.median(rms))
    limit = max(med + OUTLIER_K * 1.4826 * float(np.median(np.abs(rms - med))), OUTLIER_MIN_PX)
    keep = [k for k in range(len(obs)) if rms[k] <= limit]
    rejected: dict[int, str] = {}
    if len(keep) < len(obs) and len(keep) >= 3:
        for k in set(range(len(obs))) - set(keep):
            rejected[obs[k].index] = (
                f"outlier: {rms[k]:.2f} px after refinement (limit {limit:.2f} px, "
                f"{OUTLIER_K:g} robust sigmas above the median {med:.2f} px); a stale flange "
                "pose or a misdetection"
            )
            log.warning("hand-eye: frame %d dropped: %s", obs[k].index, rejected[obs[k].index])
        X, Y, _ = _refine(X, Y, cam, A[keep], [dets[k] for k in keep])
    return X, Y, rejected


def _warn_if_weak(rms_px: float, std: Uncertainty, cam: Intrinsics) -> None:
    """Warn when the refined answer's reprojection RMS is above what this image size allows,
    or when the data pins the camera down only loosely."""
    rms_limit = rms_limit_px(cam.width, cam.height)
    if rms_px > rms_limit:
        log.warning(
            "hand-eye reprojection RMS %.2f px is above %.2f px (0.15%% of this %dx%d image's "
            "diagonal): check the flange poses' time alignment, the intrinsics and the target "
            "size",
            rms_px,
            rms_limit,
            cam.width,
            cam.height,
        )
    if std.translation_mm > WARN_STD_MM or std.rotation_deg > WARN_STD_DEG:
        log.warning(
            "the data pins the camera down to only %.2f mm / %.3f deg (one standard "
            "deviation): add poses with larger rotations about different axes, or bring the "
            "target closer",
            std.translation_mm,
            std.rotation_deg,
        )
