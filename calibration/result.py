"""The outcome of a calibration and its YAML file.

YAML layout (lengths in metres, pixels for image quantities)::

    mode: fixed | hand_eye
    setup: eye_to_hand | eye_in_hand | null             # hand-eye only
    T_base_cam: {matrix: 4x4, xyz: [x, y, z], quat_xyzw: [x, y, z, w]}
    intrinsics: {width, height, K: 3x3, D: [...]}
    reprojection_rms_px: float
    frames: [{index, stamp_ns, rms_px, used, reason}, ...]
    methods: [{name, T_base_cam: {...}, rms_px}, ...]   # hand-eye only, else []
    spread: {translation_mm, rotation_deg} | null        # hand-eye only
    uncertainty: {translation_mm, rotation_deg, translation_axes_mm: [3],
                  rotation_axes_deg: [3]} | null         # hand-eye only
    T_flange_target: {...} | null                        # eye-to-hand only
    T_flange_cam: {...} | null                           # eye-in-hand only
    T_base_target: {...} | null                          # eye-in-hand only
    flange_frame: str | null                             # hand-eye: the flange poses' frame
    target: {type: ..., ...} | null

``T_base_cam`` is the camera's optical frame (OpenCV: x right, y down, z forward) in the
robot base frame; for a camera on the flange (eye-in-hand) it is where the camera was at the
first image that showed the target, and ``T_flange_cam`` is the answer that holds at every
pose. When reading, ``matrix`` is authoritative; ``xyz``/``quat_xyzw`` must agree. Files
written before ``setup`` existed read as eye-to-hand.
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
    HAND_EYE = "hand_eye"  # target or camera on the flange: see Setup


class Setup(str, Enum):
    """Where the camera sits in a hand-eye calibration."""

    EYE_TO_HAND = "eye_to_hand"  # camera fixed, target on the flange
    EYE_IN_HAND = "eye_in_hand"  # camera on the flange, target fixed

    @classmethod
    def parse(cls, value: Setup | str) -> Setup:
        """A setup from its value or the CLI's spelling (``eye-in-hand``)."""
        if isinstance(value, Setup):
            return value
        try:
            return cls(str(value).replace("-", "_"))
        except ValueError:
            raise CalibrationError(
                f"hand-eye setup {value!r} is unknown; valid: eye-to-hand (camera fixed, target "
                "on the flange), eye-in-hand (camera on the flange, target fixed)"
            ) from None


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


@dataclass(frozen=True)
class Uncertainty:
    """One standard deviation of the refined hand-eye answer (X: ``T_base_cam`` eye-to-hand,
    ``T_flange_cam`` eye-in-hand) from its least-squares problem: ``translation_mm`` and
    ``rotation_deg`` are the norms of the per-axis figures (axes of X's parent frame)."""

    translation_mm: float
    rotation_deg: float
    translation_axes_mm: tuple[float, ...]
    rotation_axes_deg: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        return {
            "translation_mm": float(self.translation_mm),
            "rotation_deg": float(self.rotation_deg),
            "translation_axes_mm": [float(v) for v in self.translation_axes_mm],
            "rotation_axes_deg": [float(v) for v in self.rotation_axes_deg],
        }


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
    setup: Setup | None = None
    uncertainty: Uncertainty | None = None
    T_flange_cam: Array | None = None
    T_base_target: Array | None = None
    flange_frame: str | None = None
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
            "setup": None if self.setup is None else self.setup.value,
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
            "uncertainty": None if self.uncertainty is None else self.uncertainty.to_dict(),
            "T_flange_target": _optional_pose(self.T_flange_target),
            "T_flange_cam": _optional_pose(self.T_flange_cam),
            "T_base_target": _optional_pose(self.T_base_target),
            "flange_frame": self.flange_frame,
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


def _optional_pose(T: Array | None) -> dict[str, Any] | None:
    return None if T is None else _pose_dict(T)


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
        un = data.get("uncertainty")
        uncertainty = (
            None
            if un is None
            else Uncertainty(
                float(un["translation_mm"]),
                float(un["rotation_deg"]),
                tuple(float(v) for v in un.get("translation_axes_mm", ())),
                tuple(float(v) for v in un.get("rotation_axes_deg", ())),
            )
        )
    except (KeyError, TypeError, ValueError) as err:
        raise CalibrationError(
            f"{where}: a frame, method, spread or uncertainty entry is malformed: {err!r}"
        ) from err
    poses = {
        key: None if data.get(key) is None else _pose(data[key], f"{where} {key}")
        for key in ("T_flange_target", "T_flange_cam", "T_base_target")
    }
    setup_text = data.get("setup")
    if setup_text is None and mode is Mode.HAND_EYE:
        setup_text = Setup.EYE_TO_HAND.value  # files from before eye-in-hand existed
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
        setup=None if setup_text is None else Setup.parse(setup_text),
        uncertainty=uncertainty,
        **poses,
        flange_frame=None if data.get("flange_frame") is None else str(data["flange_frame"]),
        target=None if target is None else dict(target),
    )


def load_calibration(path: str | os.PathLike[str]) -> CalibrationResult:
    """Read and validate a calibration YAML written by ``CalibrationResult.save_yaml``."""
    p = Path(path)
    data = load_yaml(p, "calibration file", CalibrationError)
    return _result_from_dict(data, f"calibration file {p}")
