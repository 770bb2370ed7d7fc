"""Which topics of a bag hold what: detection of the RealSense topic layouts.

Two layouts are understood (``BagLayout``):

- SDK (librealsense recorder, realsense-viewer, and their ROS2 conversions)::

      /device_0/sensor_0/Depth_0/image/data               sensor_msgs/Image
      /device_0/sensor_0/Depth_0/info/camera_info         sensor_msgs/CameraInfo
      /device_0/sensor_0/Depth_0/tf/0                     geometry_msgs/Transform
      /device_0/sensor_0/option/Depth Units/value         std_msgs/Float32
      /device_0/sensor_1/Color_0/...                      (same for color)

- realsense-ros (ROS1 and ROS2 wrappers), under a namespace such as ``/camera`` or
  ``/camera/camera``::

      <ns>/color/image_raw, <ns>/color/camera_info
      <ns>/depth/image_rect_raw, <ns>/depth/camera_info
      <ns>/aligned_depth_to_color/image_raw, <ns>/aligned_depth_to_color/camera_info
      <ns>/extrinsics/depth_to_color                      realsense2_camera_msgs/Extrinsics
      /tf_static                                          tf2_msgs/TFMessage

Detection looks at topic names and message types only; it reads no message.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

from gaide_core.errors import BagError
from perception.frames import BagLayout

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
JOINT_STATE = "sensor_msgs/msg/JointState"
TRANSFORM = "geometry_msgs/msg/Transform"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
FLOAT32 = "std_msgs/msg/Float32"
RS_EXTRINSICS = "realsense2_camera_msgs/msg/Extrinsics"
TF_STATIC = "/tf_static"
#: realsense-ros publishes depth as 16UC1 millimetres (m per depth unit).
WRAPPER_DEPTH_UNITS = 0.001

_SDK_IMAGE = re.compile(
    r"^(?P<device>/device_\d+)/(?P<sensor>sensor_\d+)/(?P<stream>Depth|Color)_(?P<index>\d+)"
    r"/image/data$"
)
_SDK_DEPTH_UNITS = re.compile(r"^(?P<device>/device_\d+)/sensor_\d+/option/Depth Units/value$")
_SDK_TF = re.compile(r"/tf/(?P<reference>\d+)$")

_WRAPPER_IMAGE = re.compile(
    r"^(?P<ns>(?:/[^/]+)*)/(?P<kind>color/image_raw|depth/image_rect_raw"
    r"|aligned_depth_to_color/image_raw)$"
)
# realsense-ros image topic kind -> stream; the raw depth is preferred over the aligned one
# because it keeps the sensor's own intrinsics (alignment resamples and fills holes).
_WRAPPER_KINDS = {
    "color/image_raw": "color",
    "depth/image_rect_raw": "depth",
    "aligned_depth_to_color/image_raw": "aligned",
}

SDK_PATTERN = "/device_<n>/sensor_<n>/{Depth,Color}_<n>/image/data"
WRAPPER_PATTERN = (
    "<ns>/color/image_raw, <ns>/depth/image_rect_raw or <ns>/aligned_depth_to_color/image_raw"
)


@dataclass(frozen=True)
class StreamTopics:
    """Topics of one image stream.

    ``camera_info`` is where the layout puts the stream's CameraInfo (the bag may lack it).
    ``tf`` is the SDK extrinsics topic (``.../tf/<reference>``) and ``reference`` the
    reference stream id in its name; both None outside the SDK layout.
    """

    image: str
    camera_info: str
    tf: str | None = None
    reference: int | None = None


@dataclass(frozen=True)
class TopicMap:
    """Where each piece of a RealSense recording lives in one bag.

    ``namespace`` is the topic prefix of the camera (``/device_0``, ``/camera``,
    ``/camera/camera``). ``aligned_depth`` is True when the depth stream is realsense-ros's
    depth aligned to color (then ``T_color_depth`` is the identity).
    """

    layout: BagLayout
    namespace: str
    depth: StreamTopics | None
    color: StreamTopics | None
    aligned_depth: bool = False
    depth_units: str | None = None  # SDK: std_msgs/Float32 option topic (m per unit)
    extrinsics: str | None = None  # realsense-ros: realsense2_camera_msgs/Extrinsics topic
    tf_static: str | None = None  # realsense-ros: tf2_msgs/TFMessage topic
    joint_states: tuple[str, ...] = ()


def image_topics(topics: Mapping[str, str | None]) -> list[str]:
    """Names of all sensor_msgs/Image topics, sorted (for error messages)."""
    return sorted(name for name, msgtype in topics.items() if msgtype == IMAGE)


def detect_layout(topics: Mapping[str, str | None], namespace: str | None = None) -> TopicMap:
    """Find the RealSense topics in a bag.

    Args:
        topics: topic name -> message type (``sensor_msgs/msg/Image`` form; None when a
            topic mixes several types).
        namespace: topic prefix of the camera to use (``/device_0``, ``/camera``, ...) when
            the bag holds more than one; None to require a single camera.

    Raises:
        BagError: no RealSense image topic, or several cameras and no ``namespace``.
    """
    joint_states = tuple(sorted(n for n, t in topics.items() if t == JOINT_STATE))
    sdk = _detect_sdk(topics, namespace, joint_states)
    if sdk is not None:
        return sdk
    wrapper = _detect_wrapper(topics, namespace, joint_states)
    if wrapper is not None:
        return wrapper
    where = f" under namespace {namespace!r}" if namespace else ""
    raise BagError(
        f"no RealSense image topic{where}: expected the SDK layout ({SDK_PATTERN}) or the "
        f"realsense-ros layout ({WRAPPER_PATTERN}); image topics in the bag: "
        f"{image_topics(topics) or 'none'}"
    )


def _pick_namespace(candidates: set[str], namespace: str | None) -> str | None:
    """The one camera namespace to read, or None if there is none."""
    if namespace is not None:
        wanted = namespace.rstrip("/")
        return wanted if wanted in candidates else None
    if len(candidates) > 1:
        raise BagError(
            f"the bag holds several cameras {sorted(candidates)}; "
            "pass namespace=<one of them> to choose"
        )
    return next(iter(candidates), None)


def _detect_sdk(
    topics: Mapping[str, str | None], namespace: str | None, joint_states: tuple[str, ...]
) -> TopicMap | None:
    matches = [
        (m, name) for name, t in topics.items() if t == IMAGE and (m := _SDK_IMAGE.match(name))
    ]
    device = _pick_namespace({m["device"] for m, _ in matches}, namespace)
    if device is None:
        return None
    streams: dict[str, StreamTopics] = {}
    for m, name in sorted(matches, key=lambda x: x[1]):
        kind = m["stream"].lower()
        if m["device"] != device or kind in streams:
            # A second Depth_/Color_ stream of one device (rare) is ignored: the lowest index
            # is the one librealsense exposes as "the" depth or color stream.
            continue
        prefix = name.removesuffix("/image/data")
        tfs = sorted(
            (int(t["reference"]), topic)
            for topic, mtype in topics.items()
            if mtype == TRANSFORM
            and topic.startswith(f"{prefix}/tf/")
            and (t := _SDK_TF.search(topic))
        )
        streams[kind] = StreamTopics(
            image=name,
            camera_info=f"{prefix}/info/camera_info",
            tf=tfs[0][1] if tfs else None,
            reference=tfs[0][0] if tfs else None,
        )
    depth_units = _sdk_depth_units(topics, device, streams.get("depth"))
    return TopicMap(
        layout=BagLayout.SDK,
        namespace=device,
        depth=streams.get("depth"),
        color=streams.get("color"),
        depth_units=depth_units,
        joint_states=joint_states,
    )


def _sdk_depth_units(
    topics: Mapping[str, str | None], device: str, depth: StreamTopics | None
) -> str | None:
    """The Depth Units option topic of the depth sensor (else of any sensor of the device)."""
    if depth is not None:
        sensor = depth.image.split("/")[2]
        own = f"{device}/{sensor}/option/Depth Units/value"
        if topics.get(own) == FLOAT32:
            return own
    others = sorted(
        name
        for name, t in topics.items()
        if t == FLOAT32 and (m := _SDK_DEPTH_UNITS.match(name)) and m["device"] == device
    )
    return others[0] if others else None


def _detect_wrapper(
    topics: Mapping[str, str | None], namespace: str | None, joint_states: tuple[str, ...]
) -> TopicMap | None:
    matches = [
        (m, name) for name, t in topics.items() if t == IMAGE and (m := _WRAPPER_IMAGE.match(name))
    ]
    ns = _pick_namespace({m["ns"] for m, _ in matches}, namespace)
    if ns is None:
        return None
    found = {_WRAPPER_KINDS[m["kind"]]: name for m, name in matches if m["ns"] == ns}

    def stream(image: str) -> StreamTopics:
        info = image.removesuffix("/image_raw").removesuffix("/image_rect_raw") + "/camera_info"
        return StreamTopics(image=image, camera_info=info)

    aligned = "depth" not in found and "aligned" in found
    depth_image = found.get("depth") or found.get("aligned")
    extrinsics = f"{ns}/extrinsics/depth_to_color"
    return TopicMap(
        layout=BagLayout.ROS_WRAPPER,
        namespace=ns,
        depth=stream(depth_image) if depth_image else None,
        color=stream(found["color"]) if "color" in found else None,
        aligned_depth=aligned,
        extrinsics=extrinsics if topics.get(extrinsics) == RS_EXTRINSICS else None,
        tf_static=TF_STATIC if topics.get(TF_STATIC) == TF_MESSAGE else None,
        joint_states=joint_states,
    )
