"""read_bag on damaged ROS1 bags: corrupt chunks, truncations, a missing index, no extrinsics.

Every damaged bag is made here from a sound one the project's writer wrote with one message
per chunk (``chunk_bytes=1``), so each damage hits known messages. What should survive is
worked out from the sound bag's own index (rosbags), independently of the reader under test.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Reader

from gaide_core.errors import BagError
from perception.bag_reader import read_bag
from perception.bag_writer import SDK_STREAMS, write_bag
from perception.frames import BagLayout, Frames
from tests.conftest import run_cli, shared_data
from tests.perception.bag_samples import T_COLOR_DEPTH, assert_frames_equal, make_frames

DEPTH = f"{SDK_STREAMS['depth']}/image/data"
COLOR = f"{SDK_STREAMS['color']}/image/data"
DEPTH_INFO = f"{SDK_STREAMS['depth']}/info/camera_info"
REAL_BAG = "realsense/librealsense_single_depth_color_640x480.bag"
GARBAGE = b"\xff" * 16


def _sound_bag(
    directory: Path, rng: np.random.Generator, *, compression: str = "lz4", **kw: int
) -> tuple[Path, Frames]:
    frames = make_frames(rng, **kw)
    path = write_bag(
        directory / f"sound_{compression}.bag",
        frames,
        layout=BagLayout.SDK,
        compression=compression,
        chunk_bytes=1,
    )
    return path, frames


def _chunk_data(path: Path, topic: str, index: int) -> tuple[int, int, int]:
    """(chunk record's byte, its data's first byte, data length) in the file of the chunk
    holding ``topic``'s message ``index`` (in time order), from the sound bag's index."""
    with Reader(path) as reader:
        conn = next(c for c in reader.connections if c.topic == topic)
        pos = reader.indexes[conn.id][index].chunk_pos
        return pos, reader.chunks[pos].datapos, reader.chunks[pos].datasize


def _damaged_copy(path: Path, name: str, at: int, patch: bytes) -> Path:
    data = bytearray(path.read_bytes())
    data[at : at + len(patch)] = patch
    out = path.with_name(name)
    out.write_bytes(bytes(data))
    return out


def _warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]


# --- corrupt chunks ------------------------------------------------------------------------


@pytest.mark.parametrize("compression", ["lz4", "bz2", "none"])
def test_corrupt_chunk_in_the_middle_is_skipped_with_a_warning(
    tmp_path: Path,
    rng: np.random.Generator,
    caplog: pytest.LogCaptureFixture,
    compression: str,
) -> None:
    sound, frames = _sound_bag(tmp_path, rng, compression=compression, n_depth=5, n_color=4)
    assert frames.depth is not None and frames.color is not None
    pos, start, _ = _chunk_data(sound, DEPTH, 2)
    # lz4: a broken frame header; bz2: a broken stream header; none: a broken record header.
    bad = _damaged_copy(sound, "bad.bag", start, GARBAGE)
    with caplog.at_level(logging.WARNING, logger="perception"):
        got = read_bag(bad)
    assert got.depth is not None and got.color is not None
    keep = [0, 1, 3, 4]
    np.testing.assert_array_equal(got.depth.stamps_ns, frames.depth.stamps_ns[keep])
    for a, i in zip(got.depth.images, keep, strict=True):
        np.testing.assert_array_equal(a, frames.depth.images[i])
    assert len(got.color) == len(frames.color)
    assert got.joint_states is not None and frames.joint_states is not None
    assert len(got.joint_states.stamps_ns) == len(frames.joint_states.stamps_ns)
    assert got.T_color_depth is not None
    np.testing.assert_allclose(got.T_color_depth, T_COLOR_DEPTH, atol=1e-12)
    (warning,) = _warnings(caplog)
    assert f"1 message lost (1 on {DEPTH})" in warning
    if compression == "none":
        assert "1 message record in readable chunks could not be parsed" in warning
    else:
        error = {"lz4": "RuntimeError: LZ4F", "bz2": "OSError: Invalid data stream"}[compression]
        assert f"chunks is corrupt and was skipped (byte {pos}: {error}" in warning


@pytest.mark.parametrize(
    "lost,match",
    [
        ("depth image", rf"the depth topic {DEPTH} has no messages"),
        ("depth camera_info", r"no camera_info for the depth stream"),
    ],
)
def test_corrupt_chunk_with_what_is_needed_is_refused(
    tmp_path: Path,
    rng: np.random.Generator,
    caplog: pytest.LogCaptureFixture,
    lost: str,
    match: str,
) -> None:
    sound, _ = _sound_bag(tmp_path, rng, n_depth=1, n_color=2)
    topic = DEPTH if lost == "depth image" else DEPTH_INFO
    _, start, _ = _chunk_data(sound, topic, 0)
    bad = _damaged_copy(sound, "bad.bag", start, GARBAGE)
    with (
        caplog.at_level(logging.WARNING, logger="perception"),
        pytest.raises(BagError, match=match) as err,
    ):
        read_bag(bad)
    text = str(err.value)
    assert "the bag is damaged: 1 of " in text and "chunks is corrupt and was skipped" in text
    assert "LZ4F" in text and f"1 message lost (1 on {topic})" in text
    assert "\n" not in text
    assert _warnings(caplog) == []  # the error says it all: no warning beside it
    # What the corrupt chunk did not hold is still readable on its own.
    if lost == "depth image":
        assert len(read_bag(bad, streams=("color",)).color or ()) == 2


# --- truncations and a missing index -------------------------------------------------------


def _complete_before(path: Path, topic: str, cut: int) -> list[int]:
    """Indices (time order) of ``topic``'s messages whose chunk lies wholly before ``cut``."""
    with Reader(path) as reader:
        conn = next(c for c in reader.connections if c.topic == topic)
        return [
            i
            for i, entry in enumerate(reader.indexes[conn.id])
            if reader.chunks[entry.chunk_pos].datapos + reader.chunks[entry.chunk_pos].datasize
            <= cut
        ]


@pytest.mark.parametrize("fraction", [0.3, 0.7, 0.99])
def test_truncated_bag_reads_its_complete_chunks(
    tmp_path: Path,
    rng: np.random.Generator,
    caplog: pytest.LogCaptureFixture,
    fraction: float,
) -> None:
    sound, frames = _sound_bag(tmp_path, rng, n_depth=6, n_color=6)
    assert frames.depth is not None and frames.color is not None
    data = sound.read_bytes()
    cut = int(len(data) * fraction)
    truncated = tmp_path / "cut.bag"
    truncated.write_bytes(data[:cut])
    with caplog.at_level(logging.WARNING, logger="perception"):
        got = read_bag(truncated)
    assert got.depth is not None and got.color is not None
    for stream, want, topic in ((got.depth, frames.depth, DEPTH), (got.color, frames.color, COLOR)):
        kept = _complete_before(sound, topic, cut)
        assert kept == list(range(len(kept)))  # a prefix: the recording up to the cut
        np.testing.assert_array_equal(stream.stamps_ns, want.stamps_ns[kept])
        for a, i in zip(stream.images, kept, strict=True):
            np.testing.assert_array_equal(a, want.images[i])
    if fraction < 0.5:
        assert 0 < len(got.depth) < len(frames.depth)
    if fraction > 0.95:
        assert_frames_equal(got, frames)  # only the index at the end was cut off
    (warning,) = _warnings(caplog)
    assert "rebuilt from the" in warning and "rosbag reindex" in warning
    assert f"of {cut} are unreadable" in warning


def test_unindexed_bag_is_reindexed(
    tmp_path: Path, rng: np.random.Generator, caplog: pytest.LogCaptureFixture
) -> None:
    # rosbag record writes index_pos=0 until the bag is closed: what a crash leaves.
    sound, frames = _sound_bag(tmp_path, rng)
    at = sound.read_bytes().index(b"index_pos=") + len(b"index_pos=")
    unindexed = _damaged_copy(sound, "unindexed.bag", at, bytes(8))
    with caplog.at_level(logging.WARNING, logger="perception"):
        got = read_bag(unindexed)
    assert_frames_equal(got, frames)
    (warning,) = _warnings(caplog)
    assert "Bag is not indexed" in warning and "rebuilt from the" in warning
    assert "bytes from byte" not in warning and "lost" not in warning


def test_bag_cut_inside_its_first_chunk_is_refused(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    sound, _ = _sound_bag(tmp_path, rng, n_depth=1, n_color=1)
    _, start, size = _chunk_data(sound, DEPTH, 0)
    truncated = tmp_path / "cut.bag"
    truncated.write_bytes(sound.read_bytes()[: start + size // 2])
    # The cut chunk also held the first (and only) definition of the image topics.
    with pytest.raises(BagError, match=r"no RealSense image topic.*in the bag: none") as err:
        read_bag(truncated)
    assert "rebuilt from the" in str(err.value) and "whose messages are lost" in str(err.value)
    with Reader(sound) as reader:
        first = min(c.pos for c in reader.chunk_infos)
    header_only = tmp_path / "header.bag"
    header_only.write_bytes(sound.read_bytes()[: first + 20])
    with pytest.raises(BagError, match="no complete, readable chunk"):
        read_bag(header_only)


def test_real_recording_cut_after_its_first_chunk(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    real = shared_data(REAL_BAG)
    full = read_bag(real)
    assert full.depth is not None and full.color is not None
    _, start, size = _chunk_data(real, DEPTH, 1)  # the second depth frame's chunk
    truncated = tmp_path / "crashed.bag"
    truncated.write_bytes(real.read_bytes()[: start + size // 2])
    # librealsense wrote the color stream's extrinsics into the second chunk: lost with it.
    color_tf = f"{SDK_STREAMS['color']}/tf/0"
    with pytest.raises(BagError, match=f"no depth-to-color extrinsics.*no readable {color_tf}"):
        read_bag(truncated)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="perception"):
        got = read_bag(truncated, default_extrinsics=True)
    assert got.depth is not None and got.color is not None
    assert len(got.depth) == 1 and len(got.color) == 1
    np.testing.assert_array_equal(got.depth.images[0], full.depth.images[0])
    np.testing.assert_array_equal(got.color.images[0], full.color.images[0])
    np.testing.assert_array_equal(got.depth.intrinsics.K, full.depth.intrinsics.K)
    np.testing.assert_array_equal(got.color.intrinsics.K, full.color.intrinsics.K)
    assert got.depth_units == full.depth_units
    np.testing.assert_array_equal(got.T_color_depth, np.eye(4))
    assumed, damaged = _warnings(caplog)
    assert "assuming the RealSense SDK's default extrinsics" in assumed
    assert "rebuilt from the 1 complete chunks" in damaged


# --- missing extrinsics --------------------------------------------------------------------


@pytest.mark.parametrize(
    "layout,topics",
    [
        (BagLayout.SDK, [f"{SDK_STREAMS['depth']}/tf/0", f"{SDK_STREAMS['color']}/tf/0"]),
        (BagLayout.ROS_WRAPPER, ["/camera/extrinsics/depth_to_color", "/tf_static"]),
    ],
)
def test_missing_extrinsics_name_the_topics_and_the_opt_in(
    tmp_path: Path,
    rng: np.random.Generator,
    caplog: pytest.LogCaptureFixture,
    layout: BagLayout,
    topics: list[str],
) -> None:
    frames = make_frames(rng, T_color_depth=None, layout=layout)
    path = write_bag(tmp_path / "noext.bag", frames, layout=layout)
    with pytest.raises(BagError, match="no depth-to-color extrinsics") as err:
        read_bag(path)
    text = str(err.value)
    assert all(t in text for t in topics), text
    assert "Valid: " in text and "default_extrinsics=True" in text and "\n" not in text
    # One stream alone needs no extrinsics.
    with caplog.at_level(logging.WARNING, logger="perception"):
        assert read_bag(path, streams=("depth",)).T_color_depth is None
    assert _warnings(caplog) == []
    with caplog.at_level(logging.WARNING, logger="perception"):
        got = read_bag(path, default_extrinsics=True)
    np.testing.assert_array_equal(got.T_color_depth, np.eye(4))
    (warning,) = _warnings(caplog)
    assert "assuming the RealSense SDK's default extrinsics" in warning
    assert all(t in warning for t in topics)


# --- the command line ----------------------------------------------------------------------


def test_cli_perceive_on_a_damaged_bag_exits_3_and_writes_nothing(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    sound, _ = _sound_bag(tmp_path, rng, n_depth=1, n_color=1)
    _, start, _ = _chunk_data(sound, DEPTH, 0)
    bad = _damaged_copy(sound, "bad.bag", start, GARBAGE)
    out = tmp_path / "out"
    proc = run_cli("perceive", str(bad), "--T-base-cam=0,0,1,0,0,0,1", "-o", str(out / "scene.ply"))
    assert proc.returncode == 3, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("gaide perceive: error: ")
    assert "has no messages" in lines[0] and "the bag is damaged" in lines[0]
    assert "Traceback" not in proc.stderr
    assert not out.exists() or not any(out.iterdir())


def test_cli_perceive_opts_in_to_the_default_extrinsics(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    # With a calibration file the color stream is read too, so a bag without extrinsics is
    # refused, unless the user opts in.
    from calibration.result import CalibrationResult, FrameResidual, Mode

    frames = make_frames(rng, T_color_depth=None, layout=BagLayout.SDK)
    path = write_bag(tmp_path / "noext.bag", frames, layout=BagLayout.SDK)
    intr = frames.color.intrinsics  # type: ignore[union-attr]
    T = np.diag([1.0, -1.0, -1.0, 1.0])  # looking straight down from 2 m
    T[2, 3] = 2.0
    calib = tmp_path / "calib.yaml"
    CalibrationResult(
        mode=Mode.FIXED, T_base_cam=T, K=intr.K, D=np.zeros(5), width=intr.width,
        height=intr.height, reprojection_rms_px=0.1,
        frames=(FrameResidual(0, None, 0.1, True),),
    ).save_yaml(calib)  # fmt: skip
    args = ("perceive", str(path), "--calib", str(calib), "--no-self-filter")
    refused = run_cli(*args, "-o", str(tmp_path / "a.ply"))
    assert refused.returncode == 3 and "--default-extrinsics" in refused.stderr, refused.stderr
    assert len(refused.stderr.splitlines()) == 1 and not (tmp_path / "a.ply").exists()
    ok = run_cli(*args, "--default-extrinsics", "-o", str(tmp_path / "b.ply"))
    assert ok.returncode == 0 and (tmp_path / "b.ply").exists(), ok.stderr
