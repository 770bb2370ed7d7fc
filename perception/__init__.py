"""Perception: RealSense bags (read with rosbags, no librealsense) to point clouds in the
robot's base frame. Knows nothing of planning: the robot's own points are removed with
sphere centres the caller computes."""
