"""Depth-to-color extrinsics as the RealSense layouts store them.

All results are ``T_color_depth``: the pose of the depth optical frame in the color optical
frame, ``p_color = T_color_depth @ p_depth`` (ROS optical convention: x right, y down,
z forward; metres).

SDK layout convention. librealsense's recorder writes, for each stream S, the topic
``.../S/tf/<ref>`` holding ``rs2_extrinsics`` *from* the reference stream ``ref`` *to* S
(``device::get_extrinsics`` returns the extrinsics from the group's pin stream to S), converted
to a geometry_msgs/Transform with the translation copied and the column-major rotation turned
into a quaternion. ``rs2_extrinsics`` from A to B maps ``p_B = R @ p_A + t``, so the transform
on ``S/tf/<ref>`` is ``T_S_ref``. With depth as reference (D400: depth is stream 0 and its
``tf/0`` is the identity), color's ``tf/0`` is directly ``T_color_depth``; in general
``T_color_depth = T_color_ref @ inv(T_depth_ref)``. Check on a real D435 recording: the color
``tf/0`` translation is (+14.3, +0.6, +0.6) mm, matching ``rs-enumerate-devices -c``'s
"Extrinsic from Depth To Color" (about +15 mm along x: the RGB imager sits 15 mm to the
camera's own left of the left IR imager, the depth origin, i.e. at x = -15 mm in the depth
frame, so ``p_color.x = p_depth.x + 15 mm``).

realsense-ros convention. ``<ns>/extrinsics/depth_to_color`` (realsense2_camera_msgs/Extrinsics)
holds the same ``rs2_extrinsics`` from depth to color: a column-major ``rotation[9]`` and
``translation[3]`` (m). ``/tf_static`` holds ``T_parent_child`` for each edge
(``header.frame_id`` = parent, ``child_frame_id`` = child) of the tree
``camera_link -> camera_depth_frame -> camera_depth_optical_frame`` and
``camera_link -> camera_color_frame -> camera_color_optical_frame``.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Sequence

import numpy as np

from gaide_core.errors import BagError
from gaide_core.transforms import invert, is_rigid, make_transform
from gaide_core.types import Array

# Rotation of an optical frame (x right, y down, z forward) in its body frame (x forward,
# y left, z up), as realsense-ros publishes between camera_X_frame and camera_X_optical_frame.
R_BODY_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
T_BODY_OPTICAL = make_transform(R_BODY_OPTICAL)


def sdk_T_color_depth(T_depth_ref: Array, T_color_ref: Array) -> Array:
    """``T_color_depth`` from the SDK ``tf/<ref>`` transforms of depth and color (same ref)."""
    return T_color_ref @ invert(T_depth_ref)


def rs_extrinsics_T(rotation: Sequence[float], translation: Sequence[float], topic: str) -> Array:
    """``T_to_from`` of an ``rs2_extrinsics``-style message (column-major rotation, m)."""
    R = np.asarray(rotation, dtype=np.float64).reshape(3, 3, order="F")
    t = np.asarray(translation, dtype=np.float64).reshape(3)
    T = make_transform(R, t)
    if not is_rigid(T, tol=1e-4):
        raise BagError(
            f"{topic}: rotation {R.tolist()} is not a rotation matrix; expected an orthonormal "
            "column-major 3x3 with determinant +1"
        )
    # float32 round-off in the recorded matrix: re-orthonormalize so downstream inverses hold.
    u, _, vt = np.linalg.svd(R)
    T[:3, :3] = u @ vt
    return T


def lookup_static(
    edges: Iterable[tuple[str, str, Array]], target: str, source: str
) -> Array | None:
    """``T_target_source`` through a static transform tree, or None if they are not linked.

    Args:
        edges: ``(parent, child, T_parent_child)`` triples (a /tf_static message set).
        target: frame to express poses in.
        source: frame whose pose is wanted.
    """
    # Walk the undirected tree from `target`, carrying T_target_frame for each frame reached.
    neighbours: dict[str, list[tuple[str, Array]]] = {}
    for parent, child, T_parent_child in edges:
        neighbours.setdefault(parent, []).append((child, T_parent_child))
        neighbours.setdefault(child, []).append((parent, invert(T_parent_child)))
    if target not in neighbours or source not in neighbours:
        return None
    reached: dict[str, Array] = {target: np.eye(4)}
    queue = deque([target])
    while queue:
        frame = queue.popleft()
        if frame == source:
            return reached[frame]
        for other, T_frame_other in neighbours[frame]:
            if other not in reached:
                reached[other] = reached[frame] @ T_frame_other
                queue.append(other)
    return None


def wrapper_tf_tree(
    T_color_depth: Array, depth_optical: str, color_optical: str, link: str
) -> list[tuple[str, str, Array]]:
    """The realsense-ros static tree for given extrinsics, as ``(parent, child, T_parent_child)``.

    The depth body frame coincides with ``link`` (as in realsense-ros); the color body frame is
    placed so that ``T_color_optical_depth_optical == T_color_depth``.
    """
    depth_body = _body_frame(depth_optical)
    color_body = _body_frame(color_optical)
    # T_link_color_optical = T_link_depth_optical @ inv(T_color_depth)
    T_link_color_body = T_BODY_OPTICAL @ invert(T_color_depth) @ invert(T_BODY_OPTICAL)
    return [
        (link, depth_body, np.eye(4)),
        (depth_body, depth_optical, T_BODY_OPTICAL.copy()),
        (link, color_body, T_link_color_body),
        (color_body, color_optical, T_BODY_OPTICAL.copy()),
    ]


def _body_frame(optical: str) -> str:
    """realsense-ros body frame name of an optical frame (camera_depth_optical_frame ->
    camera_depth_frame)."""
    suffix = "_optical_frame"
    return (
        optical.removesuffix(suffix) + "_frame" if optical.endswith(suffix) else optical + "_body"
    )
