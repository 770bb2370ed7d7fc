"""The project's own recorder of synthetic RealSense bags with ground truth: a known scene
(table, boxes, a calibration target, the robot at known joint states) rendered from a camera
at a known pose, with RealSense-like depth, written in the layouts the reader understands;
and photos of markers with their true corners (``marker_images``) for the detector."""

__all__ = [
    "camera",
    "marker_images",
    "raycast",
    "record",
    "scene",
]
