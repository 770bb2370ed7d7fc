"""Small synthetic RealSense recordings for the bag reader and writer tests."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gaide_core.camera import Intrinsics
from gaide_core.errors import BagError
from gaide_core.joints import JointStates
from gaide_core.ros import BagMessage
from gaide_core.ros import write_bag as write_ros_bag
from gaide_core.transforms import from_xyz_rpy
from gaide_core.types import Array
from perception.bag_builder import MessageBuilder
from perception.frames import BagLayout, Frames, ImageStream

WIDTH, HEIGHT = 64, 48
T0_NS = 1_700_000_000_123_456_789  # a realistic wall-clock stamp (ns)
PERIOD_NS = 33_333_333  # 30 Hz
# A D435-like depth-to-color pose: 15 mm along x, a few mrad of rotation.
T_COLOR_DEPTH = from_xyz_rpy([0.0148, 0.0002, -0.0003], [0.002, -0.006, 0.004])
JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint")

# Every (layout, ROS version, storage) the writer supports.
COMBINATIONS = [
    (layout, ros, storage)
    for layout in BagLayout
    for ros, storage in ((1, "sqlite3"), (2, "sqlite3"), (2, "mcap"))
]


def combo_id(combo: tuple[BagLayout, int, str]) -> str:
    layout, ros, storage = combo
    return f"{layout.name.lower()}-ros{ros}" + (f"-{storage}" if ros == 2 else "")


def bag_path(directory: Path, name: str, ros_version: int) -> Path:
    """A new bag path: a .bag file for ROS1, a folder for ROS2."""
    return directory / (f"{name}.bag" if ros_version == 1 else name)


def intrinsics(fx: float, fy: float, cx: float, cy: float, **kw: Any) -> Intrinsics:
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return Intrinsics(width=kw.pop("width", WIDTH), height=kw.pop("height", HEIGHT), K=K, **kw)


def make_frames(
    rng: np.random.Generator,
    *,
    n_depth: int = 3,
    n_color: int = 2,
    depth_units: float | None = 0.001,
    T_color_depth: Array | None = T_COLOR_DEPTH,
    joints: bool = True,
    layout: BagLayout = BagLayout.SDK,
    depth_frame: str = "camera_depth_optical_frame",
    color_frame: str = "camera_color_optical_frame",
) -> Frames:
    """Frames with random images (full uint16 and uint8 ranges) and distinct intrinsics."""
    depth = None
    if n_depth:
        depth = ImageStream(
            intrinsics=intrinsics(50.5, 50.5, 31.7, 23.2),
            images=tuple(
                rng.integers(0, 2**16, (HEIGHT, WIDTH), dtype=np.uint16) for _ in range(n_depth)
            ),
            stamps_ns=T0_NS + PERIOD_NS * np.arange(n_depth, dtype=np.int64),
            frame_id=depth_frame,
        )
    color = None
    if n_color:
        color = ImageStream(
            intrinsics=intrinsics(
                61.25,
                61.5,
                32.1,
                24.4,
                distortion_model="plumb_bob",
                D=np.array([0.11, -0.25, 0.001, -0.002, 0.1]),
            ),
            images=tuple(
                rng.integers(0, 256, (HEIGHT, WIDTH, 3), dtype=np.uint8) for _ in range(n_color)
            ),
            stamps_ns=T0_NS + 1_000_000 + PERIOD_NS * np.arange(n_color, dtype=np.int64),
            frame_id=color_frame,
        )
    joint_states = None
    if joints:
        m = 7
        joint_states = JointStates.from_stamps(
            JOINTS,
            T0_NS - 5_000_000 + 10_000_000 * np.arange(m, dtype=np.int64),
            rng.uniform(-np.pi, np.pi, (m, len(JOINTS))),
            error=BagError,
        )
    return Frames(
        source=Path("synthetic"),
        layout=layout,
        depth=depth,
        color=color,
        depth_units=depth_units,
        T_color_depth=T_color_depth,
        joint_states=joint_states,
    )


def write_raw_bag(
    path: Path,
    builder: MessageBuilder,
    messages: Sequence[tuple[str, str, int, Any]],
    storage: str = "sqlite3",
) -> Path:
    """Write (topic, msgtype, log time ns, message) as they are: for layouts the writer
    does not make (missing topics, several cameras, realsense2_camera_msgs/Extrinsics)."""
    bag = [BagMessage(topic, msgtype, stamp, msg) for topic, msgtype, stamp, msg in messages]
    return write_ros_bag(path, bag, builder, storage=storage, error=BagError)


def assert_frames_equal(got: Frames, want: Frames, *, aligned: bool = False) -> None:
    """Everything a round trip must keep, exactly (images, stamps) or to float precision."""
    for kind in ("depth", "color"):
        a, b = getattr(got, kind), getattr(want, kind)
        assert (a is None) == (b is None), kind
        if a is None or b is None:
            continue
        assert len(a) == len(b), kind
        for x, y in zip(a.images, b.images, strict=True):
            assert x.dtype == y.dtype and x.shape == y.shape, kind
            np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(a.stamps_ns, b.stamps_ns)
        assert a.stamps_ns.dtype == np.int64
        assert (a.intrinsics.width, a.intrinsics.height) == (
            b.intrinsics.width,
            b.intrinsics.height,
        )
        np.testing.assert_allclose(a.intrinsics.K, b.intrinsics.K, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.intrinsics.D, b.intrinsics.D, rtol=0, atol=1e-12)
        assert a.intrinsics.distortion_model == b.intrinsics.distortion_model
        if not (aligned and kind == "depth"):
            assert a.frame_id == b.frame_id
    if want.depth_units is not None:
        assert got.depth_units is not None
        # SDK stores the option as float32; read_bag gives back the decimal it came from.
        assert abs(got.depth_units - want.depth_units) <= 1e-7 * want.depth_units
    if aligned:
        np.testing.assert_array_equal(got.T_color_depth, np.eye(4))
    elif want.T_color_depth is None:
        assert got.T_color_depth is None
    else:
        assert got.T_color_depth is not None
        np.testing.assert_allclose(got.T_color_depth, want.T_color_depth, rtol=0, atol=1e-12)
    if want.joint_states is None:
        assert got.joint_states is None
    else:
        assert got.joint_states is not None
        assert got.joint_states.names == want.joint_states.names
        np.testing.assert_array_equal(got.joint_states.stamps_ns, want.joint_states.stamps_ns)
        np.testing.assert_array_equal(got.joint_states.q, want.joint_states.q)
