"""The depth-to-color extrinsics a bag scan found, or a refusal naming what the bag lacks.

``T_color_depth`` (the depth optical frame in the color optical frame; ``perception.bag_tf``
gives each layout's convention) comes from the SDK's ``tf/<n>`` topics, realsense-ros's
``extrinsics/depth_to_color`` message or its ``/tf_static`` tree. Without them, reading both
streams is refused unless the caller opts in to the RealSense SDK's default (identity).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from gaide_core.errors import BagError
from gaide_core.types import Array
from perception.bag_layout import StreamTopics, TopicMap
from perception.bag_messages import decode_transform
from perception.bag_scan import STREAMS, Scan
from perception.bag_tf import lookup_static, rs_extrinsics_T, sdk_T_color_depth
from perception.frames import BagLayout

logger = logging.getLogger(__name__)

#: What ``default_extrinsics=True`` assumes when a bag records no depth-to-color extrinsics.
DEFAULT_EXTRINSICS = (
    "the RealSense SDK's default extrinsics (identity rotation, zero translation: depth and "
    "color optical frames taken to coincide, though a D400's color imager sits ~15 mm beside "
    "the depth origin)"
)
VALID_EXTRINSICS = {
    BagLayout.SDK: (
        "a geometry_msgs/Transform on both <depth stream>/tf/<n> and <color stream>/tf/<n> "
        "with the same reference stream n, as librealsense records them"
    ),
    BagLayout.ROS_WRAPPER: (
        "a realsense2_camera_msgs/Extrinsics on <ns>/extrinsics/depth_to_color, or a "
        "/tf_static tree linking the depth and color optical frames"
    ),
}


def T_color_depth(
    path: Path, layout: TopicMap, wanted: tuple[str, ...], got: Scan, *, default: bool
) -> Array | None:
    """The bag's extrinsics; without them: the SDK default if asked for, else an error when
    both streams are read (relating them is what they are for), else None."""
    if layout.depth is None or layout.color is None:
        return None  # extrinsics relate two streams
    T, missing = _extrinsics(layout, got)
    if T is not None:
        return T
    if default:
        logger.warning(
            "%s: %s; assuming %s, as default_extrinsics=True asks",
            path,
            missing,
            DEFAULT_EXTRINSICS,
        )
        return np.eye(4)
    if set(wanted) == set(STREAMS):
        raise BagError(
            f"{path}: no depth-to-color extrinsics: {missing}. Valid: "
            f"{VALID_EXTRINSICS[layout.layout]}. To assume {DEFAULT_EXTRINSICS} instead, opt "
            "in with --default-extrinsics (gaide perceive), perception.default_extrinsics: "
            "true (gaide run) or read_bag(..., default_extrinsics=True)"
        )
    # Only one stream is read: nothing to relate, so no warning.
    logger.info("%s: %s; T_color_depth is unknown", path, missing)
    return None


def _extrinsics(layout: TopicMap, got: Scan) -> tuple[Array | None, str]:
    """``T_color_depth`` (see ``perception.bag_tf`` for each layout's convention), or None and
    what the bag lacks. Both streams are in ``layout``."""
    depth, color = layout.depth, layout.color
    assert depth is not None and color is not None  # checked by the caller
    if layout.aligned_depth:
        return np.eye(4), ""
    if layout.layout is BagLayout.SDK:
        missing = [
            s.tf or s.image.removesuffix("/image/data") + "/tf/0"
            for s in (depth, color)
            if s.tf is None or s.tf not in got.first
        ]
        if missing:
            return None, f"the bag has no readable {' or '.join(missing)}"
        if depth.reference != color.reference:
            return None, (f"{depth.tf} and {color.tf} are relative to different reference streams")
        assert depth.tf is not None and color.tf is not None  # in got.first
        T = sdk_T_color_depth(
            decode_transform(got.first[depth.tf], depth.tf),
            decode_transform(got.first[color.tf], color.tf),
        )
        return T, ""
    if layout.extrinsics is not None and layout.extrinsics in got.first:
        msg = got.first[layout.extrinsics]
        return rs_extrinsics_T(msg.rotation, msg.translation, layout.extrinsics), ""
    frames = {k: _frame_id(layout, k, got) for k in STREAMS}
    if got.tf_edges and frames["depth"] and frames["color"]:
        linked = lookup_static(got.tf_edges, target=frames["color"], source=frames["depth"])
        if linked is not None:
            return linked, ""
    tf = (
        f"/tf_static does not link {frames['depth']!r} to {frames['color']!r}"
        if got.tf_edges
        else "no readable /tf_static"
    )
    return None, f"the bag has no readable {layout.namespace}/extrinsics/depth_to_color and {tf}"


def _frame_id(layout: TopicMap, kind: str, got: Scan) -> str:
    """The optical frame of a stream: its image header's, else its camera_info header's."""
    if got.frame_ids.get(kind):
        return got.frame_ids[kind]
    stream: StreamTopics | None = getattr(layout, kind)
    if stream is not None and stream.camera_info in got.first:
        return str(got.first[stream.camera_info].header.frame_id)
    return ""
