"""Pictures of clouds: Open3D's offscreen renderer in a fresh interpreter, matplotlib when it
fails or runs out of time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gaide_core.transforms import from_xyz_quat
from perception.bag_reader import read_bag
from perception.cloud import CloudCfg, scene_cloud
from perception.render import render_png
from tests.conftest import shared_data

PNG = b"\x89PNG\r\n\x1a\n"


def test_open3d_draws_the_cloud_of_a_real_bag(tmp_path: Path) -> None:
    # `gaide perceive` builds the cloud, then draws it. A forked renderer inherited the
    # OpenMP pool the cloud's filters had just run, hung in Open3D's first parallel loop
    # (a cloud of more than about 5,000 points) and gave way to matplotlib after 60 s.
    frames = read_bag(shared_data("realsense/librealsense_single_depth_color_640x480.bag"))
    cloud = scene_cloud(frames, from_xyz_quat([0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0]), CloudCfg())
    assert len(cloud) > 5_000
    out = tmp_path / "scene.png"
    # a generous bound, not a timing: the hung fork never finished at all
    assert render_png(out, cloud.points, cloud.colors, timeout_s=300.0) == "open3d"
    assert out.read_bytes()[:8] == PNG


def test_a_renderer_out_of_time_gives_way_to_matplotlib(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    rng = np.random.default_rng(0)
    out = tmp_path / "cloud.png"
    assert render_png(out, rng.uniform(-0.5, 0.5, (500, 3)), timeout_s=0.01) == "matplotlib"
    assert out.read_bytes()[:8] == PNG
    assert "did not finish" in caplog.text
    assert [p.name for p in tmp_path.iterdir()] == ["cloud.png"]  # nothing temporary left
