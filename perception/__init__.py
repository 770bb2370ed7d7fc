"""Perception: RealSense bags (read with rosbags, no librealsense) to point clouds in the
robot's base frame. Knows nothing of planning: the robot's own points are removed with
sphere centres the caller computes."""

__all__ = [
    "align",
    "bag_builder",
    "bag_damage",
    "bag_extrinsics",
    "bag_layout",
    "bag_messages",
    "bag_reader",
    "bag_scan",
    "bag_tf",
    "bag_writer",
    "cloud",
    "cloud_cfg",
    "depth",
    "frames",
    "render",
    "rosbag1_reader",
    "rosbag1_reindex",
]
