from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaide_core.camera import Intrinsics
from gaide_core.errors import PerceptionError
from gaide_core.transforms import from_xyz_rpy
from perception.cloud import load_ply, remove_inside_spheres, save_ply, scene_cloud
from perception.cloud_cfg import CloudCfg
from perception.depth import Deprojector, fuse_depth, project
from perception.frames import BagLayout, Frames, ImageStream


def _intrinsics(fx: float, cx: float, cy: float, w: int = 64, h: int = 48) -> Intrinsics:
    return Intrinsics(w, h, np.array([[fx, 0, cx], [0, fx * 1.01, cy], [0, 0, 1.0]]))


@settings(max_examples=60, deadline=None)
@given(
    fx=st.floats(30, 200),
    cx=st.floats(20, 44),
    cy=st.floats(14, 34),
    seed=st.integers(0, 2**16),
)
def test_deprojection_round_trip(fx: float, cx: float, cy: float, seed: int) -> None:
    intr = _intrinsics(fx, cx, cy)
    rng = np.random.default_rng(seed)
    depth = rng.uniform(0.2, 5.0, (intr.height, intr.width))
    depth[rng.random(depth.shape) < 0.2] = np.nan
    pts, idx = Deprojector(intr).points(depth, 0.1, 10.0)
    assert len(pts) == np.isfinite(depth).sum()
    np.testing.assert_allclose(pts[:, 2], depth.ravel()[idx])
    uv, inside = project(pts, intr)
    assert inside.all()
    np.testing.assert_allclose(uv[:, 0], idx % intr.width, atol=1e-9)
    np.testing.assert_allclose(uv[:, 1], idx // intr.width, atol=1e-9)


def test_fuse_depth_is_a_median_that_ignores_holes() -> None:
    a = np.array([[1000, 0], [0, 0]], np.uint16)
    b = np.array([[1010, 2000], [0, 0]], np.uint16)
    c = np.array([[5000, 2002], [0, 0]], np.uint16)
    fused = fuse_depth([a, b, c], 0.001)
    assert fused[0, 0] == pytest.approx(1.010)
    assert fused[0, 1] == pytest.approx(2.001)
    assert np.isnan(fused[1, 1])
    with pytest.raises(PerceptionError, match="no depth frames"):
        fuse_depth([], 0.001)


def test_points_inside_spheres_are_removed() -> None:
    pts = np.array([[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0.0]])
    keep = remove_inside_spheres(pts, np.array([[0.0, 0, 0], [1.0, 0, 0.05]]), np.array([0.1, 0.1]))
    assert keep.tolist() == [False, True, False]


def _wall_frames(distance: float = 1.0) -> tuple[Frames, np.ndarray]:
    """A camera looking at a wall `distance` m ahead, as one depth frame (mm)."""
    intr = _intrinsics(60.0, 32.0, 24.0)
    depth = np.full((intr.height, intr.width), int(distance * 1000), np.uint16)
    color = np.zeros((intr.height, intr.width, 3), np.uint8)
    color[..., 0] = 200
    frames = Frames(
        source=Path("synthetic"),
        layout=BagLayout.SDK,
        depth=ImageStream(intr, (depth,), np.array([0], np.int64)),
        color=ImageStream(intr, (color,), np.array([0], np.int64)),
        depth_units=0.001,
        T_color_depth=np.eye(4),
    )
    # camera 1 m above the base origin, looking down the base x axis
    T_base_cam = from_xyz_rpy([0, 0, 1.0], [-np.pi / 2, 0, -np.pi / 2])
    return frames, T_base_cam


def test_scene_cloud_places_a_wall_in_the_base_frame(tmp_path: Path) -> None:
    frames, T_base_cam = _wall_frames(1.0)
    cfg = CloudCfg(
        workspace_min=(-2, -2, -2), workspace_max=(2, 2, 2), voxel=0.0, outlier_neighbors=0
    )
    cloud = scene_cloud(frames, T_base_cam, cfg)
    assert len(cloud) == 64 * 48
    np.testing.assert_allclose(cloud.points[:, 0], 1.0, atol=1e-9)  # the wall is at x = 1 m
    assert cloud.colors is not None and np.allclose(cloud.colors[:, 0], 200 / 255)
    path = tmp_path / "scene.ply"
    save_ply(str(path), cloud)
    np.testing.assert_allclose(load_ply(str(path)), cloud.points, atol=1e-6)


def test_scene_cloud_crops_and_self_filters() -> None:
    frames, T_base_cam = _wall_frames(1.0)
    cfg = CloudCfg(
        workspace_min=(0, -0.1, 0.9), workspace_max=(2, 2, 2), voxel=0.0, outlier_neighbors=0
    )
    cropped = scene_cloud(frames, T_base_cam, cfg)
    assert np.all(cropped.points[:, 1] >= -0.1) and np.all(cropped.points[:, 2] >= 0.9)
    robot = (np.array([[1.0, 0.2, 1.0]]), np.array([0.1]))
    filtered = scene_cloud(frames, T_base_cam, cfg, robot_spheres=robot)
    assert 0 < filtered.counts["robot_removed"] < len(cropped)
    d = np.linalg.norm(filtered.points - robot[0][0], axis=1)
    assert d.min() > 0.1 + cfg.robot_padding


def test_scene_cloud_bad_inputs(tmp_path: Path) -> None:
    frames, T_base_cam = _wall_frames(1.0)
    far = CloudCfg(workspace_min=(5, 5, 5), workspace_max=(6, 6, 6))
    with pytest.raises(PerceptionError, match="no points left inside the workspace box"):
        scene_cloud(frames, T_base_cam, far)
    with pytest.raises(PerceptionError, match="rigid"):
        scene_cloud(frames, np.zeros((4, 4)))
    from dataclasses import replace

    with pytest.raises(PerceptionError, match="depth units unknown"):
        scene_cloud(replace(frames, depth_units=None), T_base_cam)
    with pytest.raises(PerceptionError, match="no depth frames"):
        scene_cloud(replace(frames, depth=None), T_base_cam)
    with pytest.raises(PerceptionError, match="must be below workspace_max"):
        CloudCfg(workspace_min=(1, 0, 0), workspace_max=(0, 1, 1))
    with pytest.raises(PerceptionError, match="does not exist"):
        load_ply(str(tmp_path / "none.ply"))
    junk = tmp_path / "junk.ply"
    junk.write_text("not a cloud")
    with pytest.raises(PerceptionError, match="not a PLY file"):
        load_ply(str(junk))


def test_scene_cloud_without_extrinsics() -> None:
    from dataclasses import replace

    frames, T_base_cam = _wall_frames(1.0)
    cfg = CloudCfg(
        workspace_min=(-2, -2, -2), workspace_max=(2, 2, 2), voxel=0.0, outlier_neighbors=0
    )
    unknown = replace(frames, T_color_depth=None)
    # Same pixels (depth aligned to color): the identity relates the streams.
    assert len(scene_cloud(unknown, T_base_cam, cfg)) == 64 * 48
    assert frames.color is not None
    other = replace(frames.color, intrinsics=_intrinsics(61.0, 32.0, 24.0))
    with pytest.raises(PerceptionError, match=r"extrinsics are missing.*default_extrinsics=True"):
        scene_cloud(replace(unknown, color=other), T_base_cam, cfg)


def test_a_ply_cut_short_is_refused(tmp_path: Path) -> None:
    from perception.cloud import SceneCloud, save_ply

    pts = np.random.default_rng(0).random((400, 3))
    whole = tmp_path / "whole.ply"
    save_ply(str(whole), SceneCloud(pts, None))
    np.testing.assert_allclose(load_ply(str(whole)), pts)
    data = whole.read_bytes()
    for keep in (0.5, 0.99):
        cut = tmp_path / f"cut{keep}.ply"
        cut.write_bytes(data[: int(len(data) * keep)])
        with pytest.raises(PerceptionError, match="cut short: its header announces 400 points"):
            load_ply(str(cut))
