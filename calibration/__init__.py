"""Camera-to-base calibration from images of tag36h11 targets.

Sits at the bottom of the package graph beside ``core``: robot poses (forward kinematics)
come from the caller. Modules: ``targets`` (specs, frames, textures), ``detect`` (corners),
``pnp`` (per-frame pose, robust average), ``fixed`` (target at a known base pose),
``hand_eye`` (eye-to-hand), ``scale_check`` (wrong target size vs depth), ``result`` (the
YAML), ``overlay`` (a picture to check by eye).
"""

__all__ = [
    "detect",
    "fixed",
    "frames",
    "hand_eye",
    "overlay",
    "pnp",
    "result",
    "scale_check",
    "targets",
]
