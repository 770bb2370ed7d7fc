"""Offscreen pictures of clouds (Open3D's renderer: Vulkan, or Mesa's software rasterizer on
machines without a GPU). The base frame is drawn as RGB axes (x red, y green, z blue)."""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
import open3d as o3d

from core.errors import PerceptionError

Array = npt.NDArray[np.float64]


def render_png(
    path: str | Path,
    points: Array,
    colors: Array | None = None,
    *,
    meshes: Sequence[tuple[o3d.geometry.TriangleMesh, tuple[float, float, float]]] = (),
    eye: tuple[float, float, float] = (1.5, -1.3, 1.2),
    lookat: tuple[float, float, float] = (0.3, 0.0, 0.1),
    size: tuple[int, int] = (960, 720),
    axes: float = 0.25,
) -> None:
    """Write a PNG of ``points`` (N, 3) (base frame) with optional per-point RGB colours in
    [0, 1], extra meshes (each with an RGB colour) and the base frame's axes of length
    ``axes`` (m). Written atomically."""
    try:
        with _quiet_native_output():
            renderer = o3d.visualization.rendering.OffscreenRenderer(*size)
    except Exception as err:  # Open3D raises RuntimeError subclasses without a common base
        raise PerceptionError(
            "Open3D cannot render offscreen here: install Vulkan (apt-get install -y libvulkan1 "
            f"mesa-vulkan-drivers): {err}"
        ) from err
    scene = renderer.scene
    scene.set_background([1.0, 1.0, 1.0, 1.0])
    # Filament's tone mapping pales flat colours; the points carry their real colours.
    scene.view.set_post_processing(False)
    unlit = o3d.visualization.rendering.MaterialRecord()
    unlit.shader = "defaultUnlit"
    unlit.point_size = 3.0
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, float)))
    if colors is not None:
        pcd.colors = o3d.utility.Vector3dVector(np.asarray(colors, float))
    else:
        z = np.asarray(points)[:, 2]
        shade = (z - z.min()) / max(float(np.ptp(z)), 1e-9)
        pcd.colors = o3d.utility.Vector3dVector(np.stack([0.3 + 0.5 * shade] * 3, axis=1))
    scene.add_geometry("cloud", pcd, unlit)
    lit = o3d.visualization.rendering.MaterialRecord()
    lit.shader = "defaultLit"
    for i, (mesh, rgb) in enumerate(meshes):
        m = o3d.geometry.TriangleMesh(mesh)
        m.compute_vertex_normals()
        m.paint_uniform_color(rgb)
        scene.add_geometry(f"mesh{i}", m, lit)
    if axes > 0:
        frame = o3d.geometry.TriangleMesh.create_coordinate_frame(size=axes)
        scene.add_geometry("base_frame", frame, lit)
    scene.scene.set_sun_light([-0.5, 0.5, -1.0], [1.0, 1.0, 1.0], 60000)
    scene.scene.enable_sun_light(True)
    renderer.setup_camera(50.0, list(lookat), list(eye), [0.0, 0.0, 1.0])
    image = renderer.render_to_image()
    target = Path(path)
    tmp = target.with_name(target.stem + ".tmp.png")
    if not o3d.io.write_image(Path(tmp), image):
        raise PerceptionError(f"cannot write {target}")
    tmp.replace(target)


@contextlib.contextmanager
def _quiet_native_output() -> Iterator[None]:
    """Silence what Filament prints from C++ while the renderer starts (it writes straight to
    the process's stdout/stderr, around Python's streams)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)
