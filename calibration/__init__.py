"""Camera-to-base calibration from images of tag36h11 targets.

Sits at the bottom of the package graph beside ``core``: robot poses (forward kinematics)
come from the caller. Modules: ``targets`` (specs, frames, textures), ``detect`` (corners),
``pnp`` (per-frame pose, robust average), ``fixed`` (target at a known base pose),
``hand_eye`` (eye-to-hand), ``scale_check`` (wrong target size vs depth), ``result`` (the
YAML), ``overlay`` (a picture to check by eye).
"""

from calibration.detect import Detection, detect, scan
from calibration.fixed import calibrate_fixed, load_target_pose
from calibration.hand_eye import calibrate_hand_eye
from calibration.overlay import draw_overlay, save_png
from calibration.pnp import FramePose, PoseAverage, robust_average, solve_pose
from calibration.result import (
    CalibrationResult,
    FrameResidual,
    MethodResult,
    Mode,
    Spread,
    load_calibration,
)
from calibration.targets import (
    Charuco,
    SingleTag,
    TagGrid,
    Target,
    TargetTexture,
    parse_target,
    target_from_dict,
    to_dict,
)

__all__ = [
    "CalibrationResult",
    "Charuco",
    "Detection",
    "FramePose",
    "FrameResidual",
    "MethodResult",
    "Mode",
    "PoseAverage",
    "SingleTag",
    "Spread",
    "TagGrid",
    "Target",
    "TargetTexture",
    "calibrate_fixed",
    "calibrate_hand_eye",
    "detect",
    "draw_overlay",
    "load_calibration",
    "load_target_pose",
    "parse_target",
    "robust_average",
    "save_png",
    "scan",
    "solve_pose",
    "target_from_dict",
    "to_dict",
]
