"""Fixed-target calibration: a target at a known pose in the robot base frame.

Each frame's PnP gives ``T_cam_target``; their robust average gives
``T_base_cam = T_base_target @ inv(T_cam_target)`` (camera optical frame in the base frame).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from calibration.frames import check_camera, check_stamps, not_found_error, observe
from calibration.pnp import project, robust_average
from calibration.result import CalibrationResult, FrameResidual, Mode, camera_fields
from calibration.scale_check import check_target_scale
from calibration.targets import Target, target_from_dict, to_dict
from gaide_core.errors import CalibrationError
from gaide_core.text_io import load_yaml
from gaide_core.transforms import from_xyz_quat, invert, is_rigid
from gaide_core.types import Array

log = logging.getLogger(__name__)


def calibrate_fixed(
    images: Sequence[npt.NDArray[np.uint8]],
    K: Array,
    D: Array | None,
    target: Target,
    T_base_target: Array,
    *,
    stamps_ns: Sequence[int] | None = None,
    depth_m: Sequence[Array] | None = None,
) -> CalibrationResult:
    """``T_base_cam`` from images of a target whose pose ``T_base_target`` (4, 4, m) in the
    robot base frame is known.

    ``images``: gray or RGB uint8, one camera; ``K`` (3, 3) px and ``D`` (OpenCV distortion,
    or None) its intrinsics; ``stamps_ns``: per-image time stamps (ns) for the report;
    ``depth_m``: per-image depth (m, aligned to the color image, 0/NaN = none) to catch a
    wrong target size. Raises ``CalibrationError`` when the target is never found, the size
    disagrees with depth, or ``T_base_target`` is not rigid.
    """
    T_base_target = np.asarray(T_base_target, np.float64)
    if not is_rigid(T_base_target, tol=1e-5):
        raise CalibrationError(f"T_base_target is not a rigid 4x4 transform:\n{T_base_target}")
    camera = check_camera(images, K, D)
    obs = observe(images, camera, target, check_stamps(stamps_ns, len(images)))
    found = [o for o in obs if o.pose is not None]
    if not found:
        raise not_found_error(target, obs, "need at least 1", images)
    if depth_m is not None:
        check_target_scale(
            [o.detection for o in obs],
            [None if o.pose is None else o.pose.T_cam_target for o in obs],
            depth_m,
            target,
        )
    avg = robust_average([o.pose.T_cam_target for o in found if o.pose is not None])
    T_cam_target = avg.T
    rejected = {found[i].index: why for i, why in avg.rejected}
    frames, sq_err, n_pts = [], 0.0, 0
    for o in obs:
        if o.detection is None:
            frames.append(FrameResidual(o.index, o.stamp_ns, None, False, o.reason))
            continue
        err = project(camera.K, camera.D, T_cam_target, o.detection.object_points)
        sq = np.sum((err - o.detection.image_points) ** 2, axis=1)
        rms = float(np.sqrt(sq.mean()))
        used = o.index not in rejected
        if used:
            sq_err += float(sq.sum())
            n_pts += len(sq)
        frames.append(FrameResidual(o.index, o.stamp_ns, rms, used, rejected.get(o.index, "")))
    T_base_cam = T_base_target @ invert(T_cam_target)
    rms_all = float(np.sqrt(sq_err / n_pts))
    log.info(
        "fixed calibration: %d of %d frames used, reprojection RMS %.3f px",
        len(avg.used),
        len(obs),
        rms_all,
    )
    return CalibrationResult(
        mode=Mode.FIXED,
        T_base_cam=T_base_cam,
        **camera_fields(camera),
        reprojection_rms_px=rms_all,
        frames=tuple(frames),
        target=to_dict(target),
    )


def pose_from_dict(data: Any, where: str) -> Array:
    """(4, 4) pose from ``{matrix: 4x4}`` or ``{xyz: [3], quat_xyzw: [4]}`` (m)."""
    if not isinstance(data, dict):
        raise CalibrationError(f"{where} must be a mapping with matrix or xyz + quat_xyzw")
    try:
        if "matrix" in data:
            T = np.asarray(data["matrix"], np.float64)
        elif "xyz" in data and "quat_xyzw" in data:
            xyz = np.asarray(data["xyz"], np.float64)
            quat = np.asarray(data["quat_xyzw"], np.float64)
            if xyz.shape != (3,) or quat.shape != (4,) or abs(np.linalg.norm(quat) - 1) > 1e-3:
                raise CalibrationError(
                    f"{where}: xyz must be 3 numbers and quat_xyzw a unit quaternion "
                    f"(x, y, z, w), got {data['xyz']!r}, {data['quat_xyzw']!r}"
                )
            T = from_xyz_quat(xyz, quat / np.linalg.norm(quat))
        else:
            raise CalibrationError(
                f"{where} needs matrix (4x4) or xyz + quat_xyzw, got keys {sorted(data)}"
            )
    except (TypeError, ValueError) as err:
        raise CalibrationError(f"{where} is not numeric: {err}") from err
    if not is_rigid(T, tol=1e-5):
        raise CalibrationError(f"{where} is not a rigid 4x4 transform:\n{T}")
    return T


def load_target_pose(path: str | os.PathLike[str]) -> tuple[Target, Array]:
    """The target and its pose ``T_base_target`` (4, 4, m) from a YAML file::

    target: tag36h11:id=0,size=0.08        # or {type: tag36h11, id: 0, size: 0.08}
    T_base_target: {xyz: [0.5, 0.0, 0.0], quat_xyzw: [0, 0, 0, 1]}   # or {matrix: 4x4}
    """
    p = Path(path)
    data = load_yaml(p, "target pose file", CalibrationError)
    if not isinstance(data, dict) or "target" not in data or "T_base_target" not in data:
        raise CalibrationError(
            f"target pose file {p} must be a mapping with keys 'target' and 'T_base_target'"
        )
    target = target_from_dict(data["target"])
    return target, pose_from_dict(data["T_base_target"], f"{p}: T_base_target")
