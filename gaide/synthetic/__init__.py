"""The project's own recorder of synthetic RealSense bags with ground truth: a known scene
(table, boxes, a calibration target, the robot at known joint states) rendered from a camera
at a known pose, with RealSense-like depth, written in the layouts the reader understands."""

__all__ = [
    "camera",
    "raycast",
    "record",
    "scene",
]
