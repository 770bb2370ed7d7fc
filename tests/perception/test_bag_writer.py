"""write_bag: round trips through read_bag for every layout, ROS version and storage."""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from rosbags.rosbag1 import Reader
from rosbags.rosbag1.reader import decompressors

from gaide_core.errors import BagError
from gaide_core.ros import Messages
from perception.bag_reader import read_bag
from perception.bag_writer import write_bag
from perception.frames import BagLayout, Frames, ImageStream
from tests.conftest import shared_data
from tests.perception.bag_samples import (
    COMBINATIONS,
    T0_NS,
    assert_frames_equal,
    bag_path,
    combo_id,
    intrinsics,
    make_frames,
)

REAL_BAG = "realsense/librealsense_single_depth_color_640x480.bag"


@pytest.mark.parametrize("combo", COMBINATIONS, ids=combo_id)
def test_round_trip_every_layout_version_and_storage(
    tmp_path: Path, rng: np.random.Generator, combo: tuple[BagLayout, int, str]
) -> None:
    layout, ros, storage = combo
    frames = make_frames(rng, layout=layout)
    path = write_bag(
        bag_path(tmp_path, "rt", ros), frames, layout=layout, ros_version=ros, storage=storage
    )
    assert path.exists()
    assert path.is_file() == (ros == 1)
    got = read_bag(path)
    assert got.layout is layout
    assert got.source == path
    assert_frames_equal(got, frames)


@pytest.mark.parametrize("combo", COMBINATIONS, ids=combo_id)
def test_round_trip_without_extrinsics_or_joints(
    tmp_path: Path, rng: np.random.Generator, combo: tuple[BagLayout, int, str]
) -> None:
    layout, ros, storage = combo
    frames = make_frames(rng, T_color_depth=None, joints=False, n_depth=1, n_color=1)
    path = write_bag(
        bag_path(tmp_path, "bare", ros), frames, layout=layout, ros_version=ros, storage=storage
    )
    with pytest.raises(BagError, match="no depth-to-color extrinsics"):
        read_bag(path)
    assumed = dataclasses.replace(frames, T_color_depth=np.eye(4))
    assert_frames_equal(read_bag(path, default_extrinsics=True), assumed)


@pytest.mark.parametrize("compression", ["lz4", "bz2", "none"])
def test_ros1_compression_and_chunk_size(
    tmp_path: Path, rng: np.random.Generator, compression: str
) -> None:
    frames = make_frames(rng, n_depth=3, n_color=2)
    big = write_bag(tmp_path / "big.bag", frames, layout=BagLayout.SDK, compression=compression)
    small = write_bag(
        tmp_path / "small.bag",
        frames,
        layout=BagLayout.SDK,
        compression=compression,
        chunk_bytes=1,
    )
    counts: dict[str, int] = {}
    for path in (big, small):
        assert_frames_equal(read_bag(path), frames)
        with Reader(path) as reader:
            used = {reader.chunks[c.pos].decompressor for c in reader.chunk_infos}
            assert used == {decompressors[compression]}
            counts[path.name] = len(reader.chunk_infos)
            messages = reader.message_count
    assert counts == {"big.bag": 1, "small.bag": messages}  # one message per chunk


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"compression": "zstd"}, r"compression must be one of \['lz4', 'bz2', 'none'\]"),
        ({"chunk_bytes": 0}, "chunk_bytes must be a positive number of bytes"),
        ({"chunk_bytes": 1.5}, "chunk_bytes must be a positive number of bytes"),
        ({"ros_version": 2, "chunk_bytes": 1024}, "apply to ROS1 bags only"),
        ({"ros_version": 2, "compression": "bz2"}, "apply to ROS1 bags only"),
    ],
)
def test_bad_chunk_arguments(
    tmp_path: Path, rng: np.random.Generator, kwargs: dict[str, Any], match: str
) -> None:
    name = "x" if kwargs.get("ros_version") == 2 else "x.bag"
    with pytest.raises(BagError, match=match):
        write_bag(tmp_path / name, make_frames(rng), layout=BagLayout.SDK, **kwargs)
    assert not (tmp_path / name).exists()


@pytest.mark.parametrize("ros", [1, 2])
@pytest.mark.parametrize("kind", ["depth", "color"])
def test_single_stream_round_trip(
    tmp_path: Path, rng: np.random.Generator, ros: int, kind: str
) -> None:
    frames = make_frames(
        rng, n_depth=2 if kind == "depth" else 0, n_color=2 if kind == "color" else 0
    )
    # One stream alone has no extrinsics to write, and a color stream no depth units.
    expected = dataclasses.replace(
        frames, T_color_depth=None, depth_units=0.001 if kind == "depth" else None
    )
    other = "color" if kind == "depth" else "depth"
    for layout in BagLayout:
        path = write_bag(
            bag_path(tmp_path, layout.name, ros), frames, layout=layout, ros_version=ros
        )
        assert_frames_equal(read_bag(path, streams=(kind,)), expected)
        with pytest.raises(BagError, match=f"no {other} stream"):
            read_bag(path)


@pytest.mark.parametrize("ros,storage", [(1, "sqlite3"), (2, "sqlite3"), (2, "mcap")])
def test_wrapper_namespace_and_aligned_depth(
    tmp_path: Path, rng: np.random.Generator, ros: int, storage: str
) -> None:
    frames = make_frames(rng, T_color_depth=None)
    assert frames.depth is not None and frames.color is not None
    # Aligned depth lives in the color camera's pixels.
    depth = dataclasses.replace(frames.depth, intrinsics=frames.color.intrinsics)
    frames = dataclasses.replace(frames, depth=depth)
    path = write_bag(
        bag_path(tmp_path, "aligned", ros),
        frames,
        layout=BagLayout.ROS_WRAPPER,
        ros_version=ros,
        storage=storage,
        namespace="/camera/camera",
        aligned_depth=True,
    )
    got = read_bag(path)
    assert_frames_equal(got, frames, aligned=True)
    assert got.depth is not None and got.color is not None
    assert got.depth.frame_id == got.color.frame_id  # realsense-ros stamps aligned depth so
    with pytest.raises(BagError, match="namespace"):
        read_bag(path, namespace="/camera")


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    images=st.integers(1, 3).flatmap(
        lambda n: st.tuples(st.integers(1, 12), st.integers(1, 12)).flatmap(
            lambda hw: st.lists(
                hnp.arrays(np.uint16, hw, elements=st.integers(0, 2**16 - 1)),
                min_size=n,
                max_size=n,
            )
        )
    ),
    gaps=st.lists(st.integers(1, 10**9), min_size=3, max_size=3),
    combo=st.sampled_from(COMBINATIONS),
)
def test_depth_images_round_trip_exactly(
    images: list[np.ndarray], gaps: list[int], combo: tuple[BagLayout, int, str]
) -> None:
    layout, ros, storage = combo
    h, w = images[0].shape
    stamps = T0_NS + np.cumsum(np.asarray(gaps[: len(images)], dtype=np.int64))
    depth = ImageStream(
        intrinsics=intrinsics(10.0, 11.0, w / 2, h / 2, width=w, height=h),
        images=tuple(images),
        stamps_ns=stamps,
        frame_id="d",
    )
    frames = Frames(
        source=Path("p"),
        layout=layout,
        depth=depth,
        color=None,
        depth_units=0.001,
        T_color_depth=None,
    )
    with tempfile.TemporaryDirectory() as tmp:
        path = write_bag(
            bag_path(Path(tmp), "h", ros), frames, layout=layout, ros_version=ros, storage=storage
        )
        got = read_bag(path, streams=("depth",))
    assert got.depth is not None
    assert_frames_equal(got, frames)


def test_write_leaves_no_staging_files(tmp_path: Path, rng: np.random.Generator) -> None:
    write_bag(tmp_path / "a.bag", make_frames(rng), layout=BagLayout.SDK)
    write_bag(tmp_path / "b", make_frames(rng), layout=BagLayout.SDK, ros_version=2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bag", "b"]


@pytest.mark.parametrize("ros,storage", [(1, "sqlite3"), (2, "sqlite3"), (2, "mcap")])
def test_failure_mid_write_leaves_nothing(
    tmp_path: Path,
    rng: np.random.Generator,
    monkeypatch: pytest.MonkeyPatch,
    ros: int,
    storage: str,
) -> None:
    calls = {"n": 0}
    real = Messages.serialize

    def failing(self: Messages, msg: Any, msgtype: str) -> Any:
        calls["n"] += 1
        if calls["n"] > 5:
            raise OSError("No space left on device")
        return real(self, msg, msgtype)

    monkeypatch.setattr(Messages, "serialize", failing)
    path = bag_path(tmp_path / "out", "x", ros)
    with pytest.raises(BagError, match="No space left on device"):
        write_bag(path, make_frames(rng), layout=BagLayout.SDK, ros_version=ros, storage=storage)
    assert calls["n"] == 6
    assert not path.exists()
    assert list((tmp_path / "out").iterdir()) == []


def test_existing_path_is_not_overwritten(tmp_path: Path, rng: np.random.Generator) -> None:
    path = tmp_path / "keep.bag"
    path.write_bytes(b"precious")
    with pytest.raises(BagError, match="already exists"):
        write_bag(path, make_frames(rng), layout=BagLayout.SDK)
    assert path.read_bytes() == b"precious"


def _bad_depth_dtype(frames: Frames) -> Frames:
    assert frames.depth is not None
    images = tuple(im.astype(np.float32) for im in frames.depth.images)
    return dataclasses.replace(frames, depth=dataclasses.replace(frames.depth, images=images))


@pytest.mark.parametrize(
    "change,kwargs,match",
    [
        (None, {"ros_version": 3}, "ros_version must be 1 or 2"),
        (None, {"ros_version": 2, "storage": "rosbag"}, "storage must be one of"),
        (None, {"storage": "mcap"}, "applies to ROS2"),
        (None, {"name": "x.db"}, "must be a file ending in .bag"),
        (None, {"name": "x.bag", "ros_version": 2}, "without the .bag suffix"),
        (None, {"namespace": "/camera"}, "realsense-ros layout only"),
        (None, {"layout": BagLayout.ROS_WRAPPER, "namespace": "camera/"}, "ROS name"),
        (
            lambda f: dataclasses.replace(f, depth_units=0.0001),
            {"layout": BagLayout.ROS_WRAPPER},
            "millimetres",
        ),
        (lambda f: dataclasses.replace(f, depth_units=-1.0), {}, "positive"),
        (lambda f: dataclasses.replace(f, T_color_depth=np.ones((4, 4))), {}, "rigid"),
        (_bad_depth_dtype, {}, "needs uint16"),
        (lambda f: dataclasses.replace(f, depth=None, color=None), {}, "nothing to write"),
        (
            None,
            {"layout": BagLayout.ROS_WRAPPER, "aligned_depth": True},
            "depth intrinsics must equal the color intrinsics",
        ),
    ],
)
def test_bad_arguments_raise_bag_error(
    tmp_path: Path, rng: np.random.Generator, change: Any, kwargs: dict[str, Any], match: str
) -> None:
    frames = make_frames(rng)
    if change is not None:
        frames = change(frames)
    kwargs = dict(kwargs)
    path = tmp_path / kwargs.pop("name", "x.bag")
    kwargs.setdefault("layout", BagLayout.SDK)
    with pytest.raises(BagError, match=match):
        write_bag(path, frames, **kwargs)
    assert not path.exists()
    assert list(tmp_path.iterdir()) == []


def test_ros1_bags_carry_definitions_other_tools_read(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    for layout in BagLayout:
        path = write_bag(tmp_path / f"{layout.name}.bag", make_frames(rng), layout=layout)
        with Reader(path) as reader:
            conns = {c.topic: c for c in reader.connections}
        # md5 sums as genpy computes them: a ROS1 tool checks these against its own types.
        md5 = {
            "sensor_msgs/msg/Image": "060021388200f6f0f447d0fcd9c64743",
            "sensor_msgs/msg/CameraInfo": "c9a58c1b0b154e0e6da7578cb991d214",
            "sensor_msgs/msg/JointState": "3066dcd76a6cfaef579bd0f34173e9fd",
            "tf2_msgs/msg/TFMessage": "94810edda583a504dfda3829e70d7eec",
            "geometry_msgs/msg/Transform": "ac9eff44abf714214112b05d54a3cf9b",
        }
        for conn in conns.values():
            assert conn.msgdef.data.strip(), conn.topic
            if conn.msgtype in md5:
                assert conn.digest == md5[conn.msgtype], conn.topic
            # The embedded text alone defines the type: what rosbag/rqt_bag rely on.
            store = get_typestore(Stores.EMPTY)
            store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
            assert store.generate_msgdef(conn.msgtype)[1] == conn.digest
        assert "/joint_states" in conns


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_ros2_bags_read_without_a_default_typestore(
    tmp_path: Path, rng: np.random.Generator, storage: str
) -> None:
    from rosbags.highlevel import AnyReader

    path = write_bag(
        tmp_path / "b", make_frames(rng), layout=BagLayout.SDK, ros_version=2, storage=storage
    )
    with AnyReader([path]) as reader:  # definitions come from the bag itself, no default store
        expected = reader.message_count
        decoded = [
            (c.msgtype, reader.deserialize(raw, c.msgtype)) for c, _, raw in reader.messages()
        ]
    assert len(decoded) == expected > 0
    msgtypes = {t for t, _ in decoded}
    assert "sensor_msgs/msg/Image" in msgtypes and "realsense_msgs/msg/StreamInfo" in msgtypes


def test_sdk_topics_match_the_librealsense_recorder(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    from rosbags.highlevel import AnyReader

    real = shared_data(REAL_BAG)
    path = write_bag(tmp_path / "sdk.bag", make_frames(rng, joints=False), layout=BagLayout.SDK)
    with AnyReader([real]) as r:
        real_topics = {n: i.msgtype for n, i in r.topics.items()}
    with AnyReader([path]) as r:
        ours = {n: i.msgtype for n, i in r.topics.items()}
    for topic, msgtype in ours.items():
        assert real_topics.get(topic) == msgtype, topic
