"""read_bag: the real D435 recording in both forms, layouts, selection, decoding, bad input."""

from __future__ import annotations

import dataclasses
import logging
import shutil
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaide_core.errors import BagError
from gaide_core.transforms import from_xyz_rpy, invert, rotation_angle
from perception.bag_builder import MessageBuilder
from perception.bag_layout import detect_layout
from perception.bag_messages import decode_camera_info, decode_color, decode_depth
from perception.bag_reader import read_bag
from perception.bag_tf import lookup_static, sdk_T_color_depth
from perception.bag_writer import write_bag
from perception.frames import BagLayout, Frames
from tests.conftest import shared_data
from tests.perception.bag_samples import (
    T0_NS,
    T_COLOR_DEPTH,
    assert_frames_equal,
    bag_path,
    intrinsics,
    make_frames,
    write_raw_bag,
)

REAL_BAG = "realsense/librealsense_single_depth_color_640x480.bag"
REAL_MCAP_DIR = "realsense/single_depth_color_640x480_ros2_mcap"
REAL_FORMS = {
    "ros1-bag": REAL_BAG,
    "ros2-mcap-folder": REAL_MCAP_DIR,
    "bare-mcap-file": f"{REAL_MCAP_DIR}/lrs_ros2_mcap.mcap",
}
IMAGE = "sensor_msgs/msg/Image"


# --- the real D435 recording -------------------------------------------------------------


@pytest.fixture(scope="module", params=list(REAL_FORMS), ids=list(REAL_FORMS))
def real(request: pytest.FixtureRequest) -> Frames:
    return read_bag(shared_data(REAL_FORMS[request.param]))


def test_real_recording_intrinsics(real: Frames) -> None:
    assert real.layout is BagLayout.SDK
    assert real.depth is not None and real.color is not None
    d, c = real.depth.intrinsics, real.color.intrinsics
    assert (d.width, d.height, c.width, c.height) == (640, 480, 640, 480)
    np.testing.assert_allclose(
        [d.fx, d.fy, d.cx, d.cy], [390.43, 390.43, 331.39, 242.19], atol=0.01
    )
    np.testing.assert_allclose(
        [c.fx, c.fy, c.cx, c.cy], [613.20, 613.42, 319.94, 239.18], atol=0.01
    )
    assert real.depth_units == 0.001


def test_real_recording_frames_and_depth_statistics(real: Frames) -> None:
    assert real.depth is not None and real.color is not None
    assert len(real.depth) == 2 and len(real.color) == 1
    assert all(im.shape == (480, 640) and im.dtype == np.uint16 for im in real.depth.images)
    assert real.color.images[0].shape == (480, 640, 3) and real.color.images[0].dtype == np.uint8
    assert np.all(np.diff(real.depth.stamps_ns) > 0)
    assert real.depth_units is not None
    metres = [im[im > 0] * real.depth_units for im in real.depth.images]
    for im in real.depth.images:
        assert 0.92 < np.mean(im > 0) < 0.94  # about 93 % valid pixels
    assert min(m.min() for m in metres) == pytest.approx(0.34, abs=0.01)
    assert max(m.max() for m in metres) == pytest.approx(3.18, abs=0.01)
    # A colour image of a real scene, not a constant or a channel-swapped buffer.
    assert real.color.images[0].std() > 10


def test_real_recording_extrinsics_follow_the_sdk_convention(real: Frames) -> None:
    T = real.T_color_depth
    assert T is not None
    t = T[:3, 3]
    # D435: the RGB imager is ~15 mm to the camera's left of the depth origin, so a depth point
    # has x larger by ~15 mm in the color frame ("Extrinsic from Depth To Color" in the SDK).
    assert 0.013 < np.linalg.norm(t) < 0.017
    assert t[0] > 0 and abs(t[0]) > 10 * max(abs(t[1]), abs(t[2]))
    assert rotation_angle(T[:3, :3]) < np.deg2rad(2.0)
    np.testing.assert_allclose(T[:3, 3], [0.0143113, 0.0006023, 0.0006108], atol=1e-6)


def test_real_recording_reads_identically_in_both_forms() -> None:
    ros1 = read_bag(shared_data(REAL_BAG))
    ros2 = read_bag(shared_data(REAL_MCAP_DIR))
    assert_frames_equal(ros2, ros1)


def test_real_recording_selection() -> None:
    path = shared_data(REAL_BAG)
    full = read_bag(path)
    assert full.depth is not None
    second = int(full.depth.stamps_ns[1])

    only_color = read_bag(path, streams=("color",))
    assert only_color.depth is None and only_color.color is not None
    assert len(read_bag(path, max_frames=1, streams=("depth",)).depth or ()) == 1

    late = read_bag(path, streams=("depth",), start_ns=second)
    assert late.depth is not None
    np.testing.assert_array_equal(late.depth.stamps_ns, [second])
    np.testing.assert_array_equal(late.depth.images[0], full.depth.images[1])

    early = read_bag(path, streams=("depth",), end_ns=second - 1)
    assert early.depth is not None and len(early.depth) == 1

    with pytest.raises(BagError, match=r"no color frame in the time window.*stamped"):
        read_bag(path, start_ns=second)  # the only color frame is earlier


def test_real_recording_depth_units_override_warns(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, logger="perception.bag_reader"):
        frames = read_bag(shared_data(REAL_BAG), depth_units=0.0001)
    assert frames.depth_units == 0.0001
    assert "overrides the bag's 0.001" in caplog.text


def test_truncated_real_bag(tmp_path: Path) -> None:
    real = shared_data(REAL_BAG)
    cut = tmp_path / "cut.bag"
    data = real.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(BagError, match="corrupt, truncated or not a bag"):
        read_bag(cut)


def test_truncated_real_mcap(tmp_path: Path) -> None:
    real = shared_data(REAL_MCAP_DIR)
    copy = tmp_path / "mcap"
    shutil.copytree(real, copy)
    storage = copy / "lrs_ros2_mcap.mcap"
    data = storage.read_bytes()
    storage.chmod(0o644)
    storage.write_bytes(data[: len(data) // 2])
    with pytest.raises(BagError, match="corrupt, truncated or not a bag"):
        read_bag(copy)


# --- bad input ---------------------------------------------------------------------------


def test_missing_path(tmp_path: Path) -> None:
    with pytest.raises(BagError, match=r"no such file or folder; expected a ROS1 \.bag"):
        read_bag(tmp_path / "absent.bag")


@pytest.mark.parametrize("name", ["image.png", "image.bag", "image.mcap"])
def test_png_is_not_a_bag(tmp_path: Path, rng: np.random.Generator, name: str) -> None:
    ok, png = cv2.imencode(".png", rng.integers(0, 256, (8, 8, 3), dtype=np.uint8))
    assert ok
    path = tmp_path / name
    path.write_bytes(png.tobytes())
    with pytest.raises(BagError, match="not a bag"):
        read_bag(path)


def test_random_bytes_are_not_a_bag(tmp_path: Path, rng: np.random.Generator) -> None:
    path = tmp_path / "noise.bag"
    path.write_bytes(rng.integers(0, 256, 4096, dtype=np.uint8).tobytes())
    with pytest.raises(BagError, match="not a bag"):
        read_bag(path)


def test_folder_without_metadata(tmp_path: Path) -> None:
    with pytest.raises(BagError, match=r"no metadata\.yaml"):
        read_bag(tmp_path)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"streams": ("depth", "infrared")}, "streams must be"),
        ({"streams": ()}, "streams must be"),
        ({"start_ns": 10, "end_ns": 5}, "empty time window"),
        ({"max_frames": 0}, "max_frames must be at least 1"),
        ({"depth_units": 0.0}, "depth_units must be a positive"),
    ],
)
def test_bad_arguments(tmp_path: Path, kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(BagError, match=match):
        read_bag(tmp_path / "x.bag", **kwargs)


@pytest.mark.parametrize("layout", list(BagLayout))
def test_missing_stream_lists_image_topics(
    tmp_path: Path, rng: np.random.Generator, layout: BagLayout
) -> None:
    path = write_bag(tmp_path / "color.bag", make_frames(rng, n_depth=0), layout=layout)
    with pytest.raises(BagError, match=r"no depth stream.*image topics in the bag: \['/"):
        read_bag(path)


def test_no_realsense_topics(tmp_path: Path) -> None:
    b = MessageBuilder(1)
    msg = b.image("/cam/rgb", 1, "", np.zeros((2, 2, 3), np.uint8), "rgb8")
    path = write_raw_bag(tmp_path / "other.bag", b, [("/cam/rgb", IMAGE, 1, msg)])
    with pytest.raises(BagError, match=r"no RealSense image topic.*\['/cam/rgb'\]"):
        read_bag(path)


@pytest.mark.parametrize("ros", [1, 2])
def test_missing_camera_info(tmp_path: Path, ros: int) -> None:
    b = MessageBuilder(ros)
    topic = "/camera/depth/image_rect_raw"
    msg = b.image(topic, T0_NS, "d", np.ones((4, 6), np.uint16), "16UC1")
    path = write_raw_bag(bag_path(tmp_path, "noinfo", ros), b, [(topic, IMAGE, T0_NS, msg)])
    with pytest.raises(
        BagError, match=r"no camera_info for the depth stream.*/camera/depth/camera_info"
    ):
        read_bag(path, streams=("depth",))


@pytest.mark.parametrize("ros", [1, 2])
def test_missing_depth_units(tmp_path: Path, rng: np.random.Generator, ros: int) -> None:
    frames = make_frames(rng, depth_units=None)
    path = write_bag(
        bag_path(tmp_path, "nounits", ros), frames, layout=BagLayout.SDK, ros_version=ros
    )
    with pytest.raises(BagError, match=r"records no depth units.*depth_units=.*0\.001"):
        read_bag(path)
    assert read_bag(path, depth_units=0.001).depth_units == 0.001
    assert read_bag(path, streams=("color",)).depth_units is None  # not needed for color


def test_empty_time_window(tmp_path: Path, rng: np.random.Generator) -> None:
    path = write_bag(tmp_path / "w.bag", make_frames(rng), layout=BagLayout.ROS_WRAPPER)
    with pytest.raises(BagError, match="no depth frame in the time window"):
        read_bag(path, start_ns=T0_NS + 10**12)
    with pytest.raises(BagError, match="no depth frame in the time window"):
        read_bag(path, end_ns=T0_NS - 1)


def test_time_window_and_max_frames(tmp_path: Path, rng: np.random.Generator) -> None:
    frames = make_frames(rng, n_depth=5, n_color=5)
    assert frames.depth is not None
    path = write_bag(tmp_path / "w", frames, layout=BagLayout.SDK, ros_version=2, storage="mcap")
    stamps = frames.depth.stamps_ns
    got = read_bag(path, streams=("depth",), start_ns=int(stamps[1]), end_ns=int(stamps[3]))
    assert got.depth is not None
    np.testing.assert_array_equal(got.depth.stamps_ns, stamps[1:4])
    for a, b in zip(got.depth.images, frames.depth.images[1:4], strict=True):
        np.testing.assert_array_equal(a, b)
    got = read_bag(path, start_ns=int(stamps[1]), max_frames=2)
    assert got.depth is not None and got.color is not None
    np.testing.assert_array_equal(got.depth.stamps_ns, stamps[1:3])
    assert len(got.color) == 2
    # Joint states are never windowed: every frame keeps its nearest state.
    assert got.joint_states is not None and frames.joint_states is not None
    assert len(got.joint_states.stamps_ns) == len(frames.joint_states.stamps_ns)


# --- realsense-ros specifics ---------------------------------------------------------------


def _extrinsics_typestore(b: MessageBuilder) -> None:
    from rosbags.typesys import get_types_from_msg

    text = "std_msgs/Header header\nfloat64[9] rotation\nfloat64[3] translation\n"
    b.typestore.register(get_types_from_msg(text, "realsense2_camera_msgs/msg/Extrinsics"))


def _wrapper_messages(
    b: MessageBuilder, frames: Frames, ns: str = "/camera"
) -> list[tuple[str, str, int, Any]]:
    """Images and camera_info of ``frames`` on realsense-ros topics, no extrinsics."""
    out: list[tuple[str, str, int, Any]] = []
    for kind, sub, enc, leaf in (
        ("depth", "depth", "16UC1", "image_rect_raw"),
        ("color", "color", "rgb8", "image_raw"),
    ):
        stream = getattr(frames, kind)
        for stamp, image in zip(stream.stamps_ns, stream.images, strict=True):
            topic = f"{ns}/{sub}/{leaf}"
            out.append(
                (topic, IMAGE, int(stamp), b.image(topic, int(stamp), stream.frame_id, image, enc))
            )
            info_topic = f"{ns}/{sub}/camera_info"
            info = b.camera_info(info_topic, int(stamp), stream.frame_id, stream.intrinsics)
            out.append((info_topic, "sensor_msgs/msg/CameraInfo", int(stamp), info))
    return out


@pytest.mark.parametrize("ros", [1, 2])
def test_wrapper_extrinsics_message(tmp_path: Path, rng: np.random.Generator, ros: int) -> None:
    frames = make_frames(rng, joints=False)
    b = MessageBuilder(ros)
    _extrinsics_typestore(b)
    R, t = T_COLOR_DEPTH[:3, :3], T_COLOR_DEPTH[:3, 3]
    ext = b.new(
        "realsense2_camera_msgs/msg/Extrinsics",
        header=b.header("/camera/extrinsics/depth_to_color", 0, "depth_to_color_extrinsics"),
        rotation=R.flatten(order="F"),  # rs2_extrinsics: column-major
        translation=t.copy(),
    )
    msgs = [
        ("/camera/extrinsics/depth_to_color", "realsense2_camera_msgs/msg/Extrinsics", T0_NS, ext)
    ]
    path = write_raw_bag(bag_path(tmp_path, "ext", ros), b, msgs + _wrapper_messages(b, frames))
    got = read_bag(path)
    assert got.layout is BagLayout.ROS_WRAPPER
    assert got.depth_units == 0.001
    assert got.T_color_depth is not None
    np.testing.assert_allclose(got.T_color_depth, T_COLOR_DEPTH, atol=1e-12)


def test_wrapper_without_extrinsics(
    tmp_path: Path, rng: np.random.Generator, caplog: pytest.LogCaptureFixture
) -> None:
    frames = make_frames(rng, joints=False)
    b = MessageBuilder(1)
    path = write_raw_bag(tmp_path / "noext.bag", b, _wrapper_messages(b, frames))
    with pytest.raises(BagError, match=r"no readable /camera/extrinsics/depth_to_color and no"):
        read_bag(path)  # both streams: relating them needs the extrinsics
    with caplog.at_level(logging.INFO, logger="perception"):
        got = read_bag(path, streams=("color",))
    assert got.T_color_depth is None  # one stream: nothing to relate, no warning
    assert "T_color_depth is unknown" in caplog.text
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_several_cameras_need_a_namespace(tmp_path: Path, rng: np.random.Generator) -> None:
    left, right = make_frames(rng, joints=False), make_frames(rng, joints=False)
    b = MessageBuilder(2)
    msgs = _wrapper_messages(b, left, "/left") + _wrapper_messages(b, right, "/right")
    path = write_raw_bag(tmp_path / "two", b, sorted(msgs, key=lambda m: m[2]))
    with pytest.raises(BagError, match=r"several cameras \['/left', '/right'\].*namespace="):
        read_bag(path)
    got = read_bag(path, namespace="/right", depth_units=0.001, streams=("depth",))
    assert got.depth is not None and right.depth is not None
    np.testing.assert_array_equal(got.depth.images[0], right.depth.images[0])


def test_depth_units_override_for_wrapper(tmp_path: Path, rng: np.random.Generator) -> None:
    path = write_bag(tmp_path / "w.bag", make_frames(rng), layout=BagLayout.ROS_WRAPPER)
    assert read_bag(path).depth_units == 0.001
    assert read_bag(path, depth_units=0.00025).depth_units == 0.00025


def test_joint_states_keep_the_first_message_joint_order(tmp_path: Path) -> None:
    b = MessageBuilder(1)

    def js(stamp: int, names: list[str], pos: list[float]) -> tuple[str, str, int, Any]:
        msg = b.new(
            "sensor_msgs/msg/JointState",
            header=b.header("/joint_states", stamp, ""),
            name=names,
            position=np.array(pos),
            velocity=np.zeros(0),
            effort=np.zeros(0),
        )
        return ("/joint_states", "sensor_msgs/msg/JointState", stamp, msg)

    image = b.image("/camera/color/image_raw", 5, "c", np.zeros((2, 3, 3), np.uint8), "rgb8")
    intr = intrinsics(2.0, 2.0, 1.5, 1.0, width=3, height=2)
    info = b.camera_info("/camera/color/camera_info", 5, "c", intr)
    msgs = [
        js(1, ["a", "b"], [1.0, 2.0]),
        ("/camera/color/image_raw", IMAGE, 5, image),
        ("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo", 5, info),
        js(7, ["b", "a"], [4.0, 3.0]),  # another order: reordered by name
        js(8, ["gripper"], [0.5]),  # a partial message: skipped
    ]
    got = read_bag(write_raw_bag(tmp_path / "j.bag", b, msgs), streams=("color",))
    assert got.joint_states is not None
    assert got.joint_states.names == ("a", "b")
    np.testing.assert_array_equal(got.joint_states.stamps_ns, [1, 7])
    np.testing.assert_array_equal(got.joint_states.q, [[1.0, 2.0], [3.0, 4.0]])
    np.testing.assert_array_equal(got.joint_states.at(6), [3.0, 4.0])


# --- layout detection ----------------------------------------------------------------------


@pytest.mark.parametrize("ns", ["", "/camera", "/camera/camera", "/robot/wrist_cam"])
def test_detect_wrapper_namespaces(ns: str) -> None:
    topics: dict[str, str | None] = {
        f"{ns}/color/image_raw": IMAGE,
        f"{ns}/color/camera_info": "sensor_msgs/msg/CameraInfo",
        f"{ns}/depth/image_rect_raw": IMAGE,
        f"{ns}/aligned_depth_to_color/image_raw": IMAGE,
        f"{ns}/color/image_raw/compressed": "sensor_msgs/msg/CompressedImage",
        "/tf_static": "tf2_msgs/msg/TFMessage",
        "/ur/joint_states": "sensor_msgs/msg/JointState",
    }
    layout = detect_layout(topics)
    assert layout.layout is BagLayout.ROS_WRAPPER and layout.namespace == ns
    assert layout.depth is not None and layout.color is not None
    assert layout.depth.image == f"{ns}/depth/image_rect_raw"  # raw depth preferred
    assert layout.depth.camera_info == f"{ns}/depth/camera_info"
    assert not layout.aligned_depth
    assert layout.tf_static == "/tf_static" and layout.extrinsics is None
    assert layout.joint_states == ("/ur/joint_states",)
    del topics[f"{ns}/depth/image_rect_raw"]
    aligned = detect_layout(topics)
    assert aligned.aligned_depth and aligned.depth is not None
    assert aligned.depth.camera_info == f"{ns}/aligned_depth_to_color/camera_info"


def test_detect_sdk_layout() -> None:
    topics: dict[str, str | None] = {
        "/device_0/sensor_0/Depth_0/image/data": IMAGE,
        "/device_0/sensor_0/Depth_0/tf/0": "geometry_msgs/msg/Transform",
        "/device_0/sensor_1/Color_0/image/data": IMAGE,
        "/device_0/sensor_1/Color_0/tf/0": "geometry_msgs/msg/Transform",
        "/device_0/sensor_0/option/Depth Units/value": "std_msgs/msg/Float32",
    }
    layout = detect_layout(topics)
    assert layout.layout is BagLayout.SDK and layout.namespace == "/device_0"
    assert layout.depth is not None and layout.color is not None
    assert layout.depth.camera_info == "/device_0/sensor_0/Depth_0/info/camera_info"
    assert (layout.depth.tf, layout.depth.reference) == ("/device_0/sensor_0/Depth_0/tf/0", 0)
    assert layout.color.tf == "/device_0/sensor_1/Color_0/tf/0"
    assert layout.depth_units == "/device_0/sensor_0/option/Depth Units/value"


# --- extrinsics conventions ----------------------------------------------------------------


rpy = st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3)
xyz = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3)


@settings(max_examples=50, deadline=None)
@given(a_xyz=xyz, a_rpy=rpy, b_xyz=xyz, b_rpy=rpy, p=xyz)
def test_sdk_extrinsics_compose_through_any_reference(
    a_xyz: list[float], a_rpy: list[float], b_xyz: list[float], b_rpy: list[float], p: list[float]
) -> None:
    # tf/<ref> of stream S maps reference points into S: p_S = T_S_ref @ p_ref.
    T_depth_ref, T_color_ref = from_xyz_rpy(a_xyz, a_rpy), from_xyz_rpy(b_xyz, b_rpy)
    p_ref = np.append(p, 1.0)
    T = sdk_T_color_depth(T_depth_ref, T_color_ref)
    np.testing.assert_allclose(T @ (T_depth_ref @ p_ref), T_color_ref @ p_ref, atol=1e-9)
    # With depth as reference (what librealsense records), color's tf/0 is T_color_depth.
    np.testing.assert_allclose(sdk_T_color_depth(np.eye(4), T_color_ref), T_color_ref, atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(poses=st.lists(st.tuples(xyz, rpy), min_size=4, max_size=4), extra=st.booleans())
def test_static_tf_lookup_walks_the_tree_both_ways(
    poses: list[tuple[list[float], list[float]]], extra: bool
) -> None:
    # link -> d_body -> d_opt and link -> c_body -> c_opt, edges as T_parent_child.
    T = [from_xyz_rpy(x, r) for x, r in poses]
    edges = [("link", "db", T[0]), ("db", "do", T[1]), ("link", "cb", T[2]), ("cb", "co", T[3])]
    if extra:
        edges.append(("world", "link", np.eye(4)))
    T_link_do, T_link_co = T[0] @ T[1], T[2] @ T[3]
    got = lookup_static(edges, target="co", source="do")
    assert got is not None
    np.testing.assert_allclose(got, invert(T_link_co) @ T_link_do, atol=1e-9)
    assert lookup_static(edges, target="co", source="elsewhere") is None


# --- image and camera_info decoding ------------------------------------------------------------


@pytest.mark.parametrize(
    "encoding,channels,order",
    [
        ("rgb8", 3, [0, 1, 2]),
        ("bgr8", 3, [2, 1, 0]),
        ("rgba8", 4, [0, 1, 2]),
        ("bgra8", 4, [2, 1, 0]),
        ("mono8", 1, [0, 0, 0]),
    ],
)
@pytest.mark.parametrize("pad", [0, 5])
def test_color_encodings_decode_to_rgb(
    rng: np.random.Generator, encoding: str, channels: int, order: list[int], pad: int
) -> None:
    h, w = 5, 7
    raw = rng.integers(0, 256, (h, w, channels), dtype=np.uint8)
    padded = np.concatenate([raw.reshape(h, -1), np.full((h, pad), 255, np.uint8)], axis=1)
    msg = _image_msg(padded, h, w, encoding, step=w * channels + pad)
    rgb = decode_color(msg)
    assert rgb.shape == (h, w, 3) and rgb.dtype == np.uint8
    np.testing.assert_array_equal(rgb, raw[:, :, order])


@pytest.mark.parametrize("encoding", ["16UC1", "mono16"])
@pytest.mark.parametrize("bigendian", [0, 1])
@pytest.mark.parametrize("pad", [0, 3])
def test_depth_decodes_with_step_and_endianness(
    rng: np.random.Generator, encoding: str, bigendian: int, pad: int
) -> None:
    h, w = 4, 6
    depth = rng.integers(0, 2**16, (h, w), dtype=np.uint16)
    wire = depth.astype(">u2" if bigendian else "<u2").view(np.uint8).reshape(h, 2 * w)
    padded = np.concatenate([wire, np.zeros((h, pad), np.uint8)], axis=1)
    msg = _image_msg(padded, h, w, encoding, step=2 * w + pad, bigendian=bigendian)
    got = decode_depth(msg)
    assert got.dtype == np.uint16 and got.dtype.isnative
    np.testing.assert_array_equal(got, depth)


def test_bad_images_raise(rng: np.random.Generator) -> None:
    with pytest.raises(BagError, match=r"depth encoding 'rgb8' is not supported.*16UC1"):
        decode_depth(_image_msg(np.zeros((2, 6), np.uint8), 2, 2, "rgb8", step=6))
    with pytest.raises(BagError, match=r"color encoding 'yuv422' is not supported.*bgr8"):
        decode_color(_image_msg(np.zeros((2, 4), np.uint8), 2, 2, "yuv422", step=4))
    with pytest.raises(BagError, match="step 3 B is less than"):
        decode_depth(_image_msg(np.zeros((2, 3), np.uint8), 2, 2, "16UC1", step=3))
    truncated = _image_msg(np.zeros((1, 8), np.uint8), 2, 4, "16UC1", step=8)
    with pytest.raises(BagError, match="needs 16 B"):
        decode_depth(truncated)


@pytest.mark.parametrize("ros", [1, 2])
def test_camera_info_fields_of_both_ros_versions(ros: int, rng: np.random.Generator) -> None:
    frames = make_frames(rng)
    assert frames.color is not None
    intr = frames.color.intrinsics
    msg = MessageBuilder(ros).camera_info("/info", 0, "c", intr)
    assert hasattr(msg, "K" if ros == 1 else "k")
    got = decode_camera_info(msg, "/info", (intr.width, intr.height))
    np.testing.assert_array_equal(got.K, intr.K)
    np.testing.assert_array_equal(got.D, intr.D)
    with pytest.raises(BagError, match="camera_info is 64x48 but the images are 32x24"):
        decode_camera_info(msg, "/info", (32, 24))
    unsized = dataclasses.replace(msg, width=0, height=0)
    assert decode_camera_info(unsized, "/info", (32, 24)).width == 32
    uncalibrated = dataclasses.replace(msg, **{"K" if ros == 1 else "k": np.zeros(9)})
    with pytest.raises(BagError, match="/info: camera matrix K"):
        decode_camera_info(uncalibrated, "/info", (64, 48))


def _image_msg(
    rows: np.ndarray, h: int, w: int, encoding: str, *, step: int, bigendian: int = 0
) -> Any:
    b = MessageBuilder(2)
    return b.new(
        IMAGE,
        header=b.header("/img", 0, ""),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=bigendian,
        step=step,
        data=np.ascontiguousarray(rows).reshape(-1),
    )
