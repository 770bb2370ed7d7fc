"""The outcome of a calibration and its YAML file.

YAML layout (lengths in metres, pixels for image quantities)::

    mode: fixed | hand_eye
    T_base_cam: {matrix: 4x4, xyz: [x, y, z], quat_xyzw: [x, y, z, w]}
    intrinsics: {width, height, K: 3x3, D: [...]}
    reprojection_rms_px: float
    frames: [{index, stamp_ns, rms_px, used, reason}, ...]
    methods: [{name, T_base_cam: {...}, rms_px}, ...]   # hand-eye only, else []
    spread: {translation_mm, rotation_deg} | null        # hand-eye only
    T_flange_target: {...} | null                        # hand-eye only
    target: {type: ..., ...} | null

``T_base_cam`` is the camera's optical frame (OpenCV: x right, y down, z forward) in the
robot base frame. When reading, ``matrix`` is authoritative; ``xyz``/``quat_xyzw`` must agree.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from gaide_core.atomic import write_bytes_atomic
from gaide_core.camera import Intrinsics
from gaide_core.errors import CalibrationError
from gaide_core.text_io import load_yaml
from gaide_core.transforms import from_xyz_quat, is_rigid, to_xyz_quat, transform_error
from gaide_core.types import Array


class Mode(str, Enum):
    """How the camera was calibrated."""

    FIXED = "fixed"  # target at a known pose in the base frame
    HAND_EYE = "hand_eye"  # eye-to-hand: target on the flange, camera fixed


@dataclass(frozen=True)
class FrameResidual:
    """One input frame: ``rms_px`` reprojection RMS (px) at the final calibration (None if
    the target was not found), whether it was ``used``, and ``reason`` when it was not."""

    index: int
    stamp_ns: int | None
    rms_px: float | None
    used: bool
    reason: str = ""


@dataclass(frozen=True, eq=False)
class MethodResult:
    """One hand-eye method's ``T_base_cam`` (4, 4) and its reprojection RMS (px)."""

    name: str
    T_base_cam: Array
    rms_px: float


@dataclass(frozen=True)
class Spread:
    """Disagreement of the hand-eye methods: largest pairwise difference of ``T_base_cam``."""

    translation_mm: float
    rotation_deg: float


def camera_fields(camera: Intrinsics) -> dict[str, Any]:
    """The :class:`CalibrationResult` fields of the camera the result is for."""
    return {"K": camera.K, "D": camera.D, "width": camera.width, "height": camera.height}


@dataclass(frozen=True, kw_only=True, eq=False)
class CalibrationResult:
    """Camera-to-base calibration.

    ``T_base_cam`` (4, 4): camera optical frame in the robot base frame (m). ``K`` (3, 3),
    ``D`` (n,): the intrinsics used (px), for ``width`` x ``height`` images.
    ``reprojection_rms_px``: RMS over all points of the used frames at the final estimate.
    """

    mode: Mode
    T_base_cam: Array
    K: Array
    D: Array
    width: int
    height: int
    reprojection_rms_px: float
    frames: tuple[FrameResidual, ...]
    methods: tuple[MethodResult, ...] = ()
    spread: Spread | None = None
    T_flange_target: Array | None = None
    target: Mapping[str, Any] | None = field(default=None)

    def __post_init__(self) -> None:
        if not is_rigid(self.T_base_cam):
            raise CalibrationError(f"T_base_cam is not a rigid transform:\n{self.T_base_cam}")
        if np.shape(self.K) != (3, 3):
            raise CalibrationError(f"K must be 3x3, got shape {np.shape(self.K)}")

    def to_dict(self) -> dict[str, Any]:
        """YAML-ready mapping (plain Python types), the layout in the module docstring."""
        return {
            "mode": self.mode.value,
            "T_base_cam": _pose_dict(self.T_base_cam),
            "intrinsics": {
                "width": int(self.width),
                "height": int(self.height),
                "K": _floats(self.K),
                "D": _floats(np.ravel(self.D)),
            },
            "reprojection_rms_px": float(self.reprojection_rms_px),
            "frames": [
                {
                    "index": f.index,
                    "stamp_ns": f.stamp_ns,
                    "rms_px": None if f.rms_px is None else float(f.rms_px),
                    "used": f.used,
                    "reason": f.reason,
                }
                for f in self.frames
            ],
            "methods": [
                {"name": m.name, "T_base_cam": _pose_dict(m.T_base_cam), "rms_px": float(m.rms_px)}
                for m in self.methods
            ],
            "spread": None
            if self.spread is None
            else {
                "translation_mm": float(self.spread.translation_mm),
                "rotation_deg": float(self.spread.rotation_deg),
            },
            "T_flange_target": None
            if self.T_flange_target is None
            else _pose_dict(self.T_flange_target),
            "target": None if self.target is None else dict(self.target),
        }

    def save_yaml(self, path: str | os.PathLike[str]) -> Path:
        """Write the YAML atomically (temporary file, then rename); returns the path."""
        text = yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=None)
        return write_bytes_atomic(path, text.encode(), CalibrationError)


def _floats(a: npt.ArrayLike) -> Any:
    return np.asarray(a, np.float64).tolist()


def _pose_dict(T: Array) -> dict[str, Any]:
    xyz, quat = to_xyz_quat(np.asarray(T, np.float64))
    return {"matrix": _floats(T), "xyz": _floats(xyz), "quat_xyzw": _floats(quat)}


def _need(data: Mapping[str, Any], key: str, where: str) -> Any:
    if not isinstance(data, Mapping):
        raise CalibrationError(f"{where} must be a mapping, got {data!r}")
    if key not in data:
        raise CalibrationError(f"{where} lacks the key {key!r} (keys: {sorted(data)})")
    return data[key]


def _matrix(value: Any, shape: tuple[int, ...], where: str) -> Array:
    try:
        a = np.asarray(value, np.float64)
    except (TypeError, ValueError) as err:
        raise CalibrationError(f"{where} is not numeric: {value!r}") from err
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise CalibrationError(f"{where} must be {shape} finite numbers, got {value!r}")
    return a


def _pose(data: Any, where: str) -> Array:
    T = _matrix(_need(data, "matrix", where), (4, 4), f"{where}.matrix")
    if not is_rigid(T, tol=1e-5):
        raise CalibrationError(
            f"{where}.matrix is not a rigid transform (rotation must be orthonormal with "
            f"det +1, last row 0 0 0 1):\n{T}"
        )
    if "xyz" in data and "quat_xyzw" in data:
        xyz = _matrix(data["xyz"], (3,), f"{where}.xyz")
        quat = _matrix(data["quat_xyzw"], (4,), f"{where}.quat_xyzw")
        if abs(np.linalg.norm(quat) - 1) > 1e-4:
            raise CalibrationError(f"{where}.quat_xyzw {quat.tolist()} is not a unit quaternion")
        dt, dr = transform_error(from_xyz_quat(xyz, quat), T)
        if dt > 1e-5 or dr > 1e-4:  # a hand-edited mismatch, not float rounding
            raise CalibrationError(
                f"{where}: xyz/quat_xyzw disagree with matrix by {dt * 1e3:.3f} mm, "
                f"{math.degrees(dr):.4f} deg"
            )
    return T


def _result_from_dict(data: Any, where: str) -> CalibrationResult:
    if not isinstance(data, Mapping):
        raise CalibrationError(f"{where} must hold a YAML mapping, got {type(data).__name__}")
    mode_text = _need(data, "mode", where)
    try:
        mode = Mode(mode_text)
    except ValueError as err:
        raise CalibrationError(
            f"{where}: mode {mode_text!r} is unknown; valid: {[m.value for m in Mode]}"
        ) from err
    intr = _need(data, "intrinsics", where)
    K = _matrix(_need(intr, "K", f"{where} intrinsics"), (3, 3), f"{where} intrinsics.K")
    D_raw = _need(intr, "D", f"{where} intrinsics")
    if not isinstance(D_raw, list):
        raise CalibrationError(f"{where}: intrinsics.D must be a list, got {D_raw!r}")
    D = _matrix(D_raw, (len(D_raw),), f"{where} intrinsics.D")
    width, height = _need(intr, "width", where), _need(intr, "height", where)
    if not all(isinstance(v, int) and v > 0 for v in (width, height)):
        raise CalibrationError(f"{where}: image size {width}x{height} must be positive integers")
    rms = _need(data, "reprojection_rms_px", where)
    if not isinstance(rms, (int, float)) or not rms >= 0:
        raise CalibrationError(f"{where}: reprojection_rms_px must be >= 0, got {rms!r}")
    try:
        frames = tuple(
            FrameResidual(
                index=int(f["index"]),
                stamp_ns=None if f["stamp_ns"] is None else int(f["stamp_ns"]),
                rms_px=None if f["rms_px"] is None else float(f["rms_px"]),
                used=bool(f["used"]),
                reason=str(f.get("reason", "")),
            )
            for f in _need(data, "frames", where)
        )
        methods = tuple(
            MethodResult(
                str(m["name"]), _pose(m["T_base_cam"], f"{where} method"), float(m["rms_px"])
            )
            for m in data.get("methods") or ()
        )
        sp = data.get("spread")
        spread = (
            None if sp is None else Spread(float(sp["translation_mm"]), float(sp["rotation_deg"]))
        )
    except (KeyError, TypeError, ValueError) as err:
        raise CalibrationError(
            f"{where}: a frame, method or spread entry is malformed: {err!r}"
        ) from err
    ft = data.get("T_flange_target")
    target = data.get("target")
    if target is not None and not isinstance(target, Mapping):
        raise CalibrationError(f"{where}: target must be a mapping, got {target!r}")
    return CalibrationResult(
        mode=mode,
        T_base_cam=_pose(_need(data, "T_base_cam", where), f"{where} T_base_cam"),
        K=K,
        D=D,
        width=width,
        height=height,
        reprojection_rms_px=float(rms),
        frames=frames,
        methods=methods,
        spread=spread,
        T_flange_target=None if ft is None else _pose(ft, f"{where} T_flange_target"),
        target=None if target is None else dict(target),
    )


def load_calibration(path: str | os.PathLike[str]) -> CalibrationResult:
    """Read and validate a calibration YAML written by ``CalibrationResult.save_yaml``."""
    p = Path(path)
    data = load_yaml(p, "calibration file", CalibrationError)
    return _result_from_dict(data, f"calibration file {p}")
