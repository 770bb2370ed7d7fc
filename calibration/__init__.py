"""Camera-to-base calibration from images of marker targets (any OpenCV dictionary).

Sits at the bottom of the package graph beside ``core``: robot poses (forward kinematics)
come from the caller. Modules: ``targets`` (specs, dictionaries, frames, textures),
``detect`` (markers and corners), ``pnp`` (per-frame pose, robust average), ``fixed`` (target
at a known base pose), ``hand_eye`` (eye-to-hand and eye-in-hand), ``scale_check`` (wrong
target size vs depth), ``inputs`` (photos and intrinsics files), ``pose_files`` (flange
poses per photo), ``result`` (the YAML), ``ros_export`` (hand-eye YAML, static TF line),
``overlay`` (a picture to check by eye).
"""

__all__ = [
    "detect",
    "fixed",
    "frames",
    "hand_eye",
    "inputs",
    "overlay",
    "pnp",
    "pose_files",
    "result",
    "ros_export",
    "scale_check",
    "targets",
]
