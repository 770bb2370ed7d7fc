"""Offscreen pictures of clouds, with the base frame drawn as RGB axes (x red, y green,
z blue).

Open3D's renderer (Filament on Vulkan, or Mesa's software rasterizer on machines without a
GPU) draws the picture in a child process: with a lit material, its
``render_to_image`` ran for minutes on the software rasterizer under load (seen here), and a
child can be stopped. If it fails or runs past the timeout, matplotlib draws the picture instead.

The child is a fresh interpreter (``python -m perception.render JOB OUT``), not a fork: a
process that has run an OpenMP region (numpy's BLAS, OpenCV, Open3D's own filters) leaves
GNU OpenMP's thread pool unusable in a forked child, and Open3D's next parallel loop there
(adding a cloud of more than about 5,000 points) waits forever; ``gaide perceive`` on a real
bag hit the timeout every time that way.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from gaide_core.atomic import write_file_atomic
from gaide_core.errors import PerceptionError
from gaide_core.native_output import quiet_native_output
from gaide_core.types import Array

log = logging.getLogger(__name__)


def render_png(
    path: str | Path,
    points: Array,
    colors: Array | None = None,
    *,
    eye: tuple[float, float, float] = (1.5, -1.3, 1.2),
    lookat: tuple[float, float, float] = (0.3, 0.0, 0.1),
    size: tuple[int, int] = (960, 720),
    axes: float = 0.25,
    timeout_s: float = 60.0,
) -> str:
    """Write a PNG of ``points`` (N, 3) (base frame) with optional per-point RGB colours in
    [0, 1] and the base frame's axes of length ``axes`` (m), atomically. (Scenes with meshes
    are ray-cast instead: Filament draws triangles slowly on the software rasterizer.)
    Returns which renderer drew it: "open3d" or "matplotlib"."""
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise PerceptionError(f"nothing to draw: points must be (N, 3) with N > 0, got {pts.shape}")
    cols = _colors(pts, colors)
    drawn: list[str] = []

    def write(tmp: Path) -> None:
        drawn.append(_render(tmp, pts, cols, eye, lookat, size, axes, timeout_s))

    write_file_atomic(path, write, PerceptionError)
    return drawn[0]


def _render(
    tmp: Path,
    pts: Array,
    cols: Array,
    eye: tuple[float, float, float],
    lookat: tuple[float, float, float],
    size: tuple[int, int],
    axes: float,
    timeout_s: float,
) -> str:
    """Draw into ``tmp`` with Open3D (in a fresh interpreter, given ``timeout_s``), else
    matplotlib; returns which drew it."""
    with tempfile.TemporaryDirectory(prefix="gaide-render-") as folder:
        job = Path(folder) / "job.npz"
        np.savez(job, points=pts, colors=cols, eye=eye, lookat=lookat, size=size, axes=axes)
        command = [sys.executable, "-m", "perception.render", str(job), str(tmp)]
        # the child finds this package even where it is not installed (a source checkout)
        root = str(Path(__file__).resolve().parents[1])
        env = {
            **os.environ,
            "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])),
        }
        try:
            done = subprocess.run(
                command, capture_output=True, timeout=timeout_s, check=False, env=env
            )
            drawn = done.returncode == 0 and tmp.is_file()
            if not drawn:
                log.info(
                    "Open3D's renderer failed (exit %d): %s",
                    done.returncode,
                    done.stderr.decode(errors="replace").strip()[-500:],
                )
        except subprocess.TimeoutExpired:  # run() has killed the child
            log.warning(
                "Open3D's renderer did not finish in %.0f s; drawing with matplotlib", timeout_s
            )
            drawn = False
    if drawn:
        return "open3d"
    tmp.unlink(missing_ok=True)
    _matplotlib_png(tmp, pts, cols, eye, lookat, size, axes)
    return "matplotlib"


def _colors(points: Array, colors: Array | None) -> Array:
    if colors is not None:
        return np.clip(np.asarray(colors, float), 0.0, 1.0)
    z = points[:, 2]
    shade = (z - z.min()) / max(float(np.ptp(z)), 1e-9)
    return np.stack([0.3 + 0.5 * shade] * 3, axis=1)


def _open3d_child(job: str, out: str) -> None:
    """The child's work: the job's cloud drawn into ``out``; exits 0 when written."""
    import open3d as o3d

    with np.load(job) as data:
        points, colors, axes = data["points"], data["colors"], float(data["axes"])
        eye, lookat = data["eye"].tolist(), data["lookat"].tolist()
        width, height = (int(v) for v in data["size"])

    with quiet_native_output():
        renderer = o3d.visualization.rendering.OffscreenRenderer(width, height)
    scene = renderer.scene
    scene.set_background([1.0, 1.0, 1.0, 1.0])
    # Filament's tone mapping pales flat colours; the points carry their real colours.
    scene.view.set_post_processing(False)
    unlit = o3d.visualization.rendering.MaterialRecord()
    unlit.shader = "defaultUnlit"
    unlit.point_size = 3.0  # pixels
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pcd.colors = o3d.utility.Vector3dVector(colors)
    scene.add_geometry("cloud", pcd, unlit)
    # Unlit only: Filament's lit shader takes ~13 s a frame on the software rasterizer.
    if axes > 0:
        scene.add_geometry(
            "base_frame", o3d.geometry.TriangleMesh.create_coordinate_frame(size=axes), unlit
        )
    renderer.setup_camera(50.0, list(lookat), list(eye), [0.0, 0.0, 1.0])
    image = renderer.render_to_image()
    ok = o3d.io.write_image(Path(out), image)
    # Leave without Filament's teardown, which takes seconds on the software rasterizer.
    os._exit(0 if ok else 1)


def _matplotlib_png(
    tmp: Path,
    points: Array,
    colors: Array,
    eye: tuple[float, float, float],
    lookat: tuple[float, float, float],
    size: tuple[int, int],
    axes: float,
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    ax = fig.add_subplot(projection="3d")
    pick = slice(None, None, max(1, len(points) // 40_000))
    ax.scatter(*points[pick].T, c=colors[pick], s=1.0, linewidths=0)
    for axis, color in zip(np.eye(3) * axes, ("r", "g", "b"), strict=True):
        ax.quiver(0, 0, 0, *axis, color=color, linewidth=2)
    d = np.asarray(eye) - np.asarray(lookat)
    ax.view_init(
        elev=float(np.degrees(np.arctan2(d[2], np.hypot(d[0], d[1])))),
        azim=float(np.degrees(np.arctan2(d[1], d[0]))),
    )
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre, half = (lo + hi) / 2, float(np.max(hi - lo)) / 2
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    fig.savefig(tmp)
    plt.close(fig)


if __name__ == "__main__":
    _open3d_child(sys.argv[1], sys.argv[2])
