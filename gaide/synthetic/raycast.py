"""Color and depth images of a scene by ray casting (Open3D's RaycastingScene; no display).

Why by hand: the scene mixes flat-shaded primitives, the robot's meshes and one textured
plane (the calibration target); Open3D's ray caster gives hits, normals and geometry ids,
and the shading and texture look-up on top of it are a few array operations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import open3d as o3d
import trimesh

from gaide_core.camera import Intrinsics
from gaide_core.types import Array

_LIGHT = np.array([0.3, -0.4, 0.85]) / np.linalg.norm([0.3, -0.4, 0.85])


@dataclass(frozen=True)
class Texture:
    """A grayscale image on the z = 0 plane of its frame (see calibration.targets)."""

    image: npt.NDArray[np.uint8]  # (H, W)
    extent: tuple[float, float, float, float]  # x_min, x_max, y_min, y_max (m)
    T_base_tex: Array  # (4, 4) texture frame in the base frame


class RaycastScene:
    """Meshes (base frame) with flat colours, at most one of them textured."""

    def __init__(self) -> None:
        self._scene = o3d.t.geometry.RaycastingScene()
        self._colors: list[Array] = []
        self._texture: tuple[int, Texture] | None = None

    def add(
        self, mesh: trimesh.Trimesh, rgb: tuple[float, float, float], texture: Texture | None = None
    ) -> None:
        tmesh = o3d.t.geometry.TriangleMesh()
        tmesh.vertex.positions = o3d.core.Tensor.from_numpy(
            np.ascontiguousarray(mesh.vertices, np.float32)
        )
        tmesh.triangle.indices = o3d.core.Tensor.from_numpy(
            np.ascontiguousarray(mesh.faces, np.int32)
        )
        gid = self._scene.add_triangles(tmesh)
        self._colors.append(np.asarray(rgb, float))
        if texture is not None:
            self._texture = (gid, texture)

    def cast(self, intr: Intrinsics, T_base_cam: Array, offsets: Array) -> dict[str, Array]:
        """Cast one ray per pixel and per sub-pixel offset (K, 2): returns hit distance ``t``
        (K, H, W) along unit rays, ``z`` in the camera frame, ``cos`` of incidence, ``rgb``."""
        v, u = np.mgrid[0 : intr.height, 0 : intr.width].astype(np.float64)
        out: dict[str, list[Array]] = {"z": [], "cos": [], "rgb": []}
        R, t = T_base_cam[:3, :3], T_base_cam[:3, 3]
        for du, dv in offsets:
            d_cam = np.stack(
                [(u + du - intr.cx) / intr.fx, (v + dv - intr.cy) / intr.fy, np.ones_like(u)], -1
            )
            d_cam /= np.linalg.norm(d_cam, axis=-1, keepdims=True)
            d_base = d_cam @ R.T
            rays = np.concatenate([np.broadcast_to(t, d_base.shape), d_base], axis=-1).astype(
                np.float32
            )
            hit = self._scene.cast_rays(o3d.core.Tensor.from_numpy(np.ascontiguousarray(rays)))
            dist = hit["t_hit"].numpy().astype(np.float64)
            ids = hit["geometry_ids"].numpy().astype(np.int64)
            normals = hit["primitive_normals"].numpy().astype(np.float64)
            missed = ~np.isfinite(dist)
            dist[missed] = np.nan
            z = dist * d_cam[..., 2]
            cos = np.einsum("hwi,hwi->hw", normals, d_base)
            palette = np.asarray([*self._colors, np.ones(3)])
            base = palette[np.where(missed, len(self._colors), ids)]
            shade = 0.35 + 0.65 * np.abs(normals @ _LIGHT)
            rgb = base * shade[..., None]
            rgb[missed] = (0.92, 0.92, 0.95)
            if self._texture is not None:
                gid, tex = self._texture
                on = ids == gid
                if np.any(on):
                    p = t + d_base[on] * dist[on, None]
                    local = (p - tex.T_base_tex[:3, 3]) @ tex.T_base_tex[:3, :3]
                    gray = _sample(tex, local[:, 0], local[:, 1])
                    rgb[on] = (gray[:, None] / 255.0) * (0.55 + 0.45 * shade[on, None])
            out["z"].append(z)
            out["cos"].append(cos)
            out["rgb"].append(rgb)
        return {k: np.stack(vals) for k, vals in out.items()}


def _sample(tex: Texture, x: Array, y: Array) -> Array:
    """Bilinear texture look-up at target-frame coordinates (m); white outside."""
    h, w = tex.image.shape
    x0, x1, y0, y1 = tex.extent
    c = (x - x0) / (x1 - x0) * w - 0.5
    r = (y1 - y) / (y1 - y0) * h - 0.5
    img = np.pad(tex.image.astype(np.float64), 1, constant_values=255.0)
    c, r = np.clip(c + 1, 0, w), np.clip(r + 1, 0, h)
    c0, r0 = np.floor(c).astype(np.int64), np.floor(r).astype(np.int64)
    fc, fr = c - c0, r - r0
    c1, r1 = np.minimum(c0 + 1, w + 1), np.minimum(r0 + 1, h + 1)
    top = img[r0, c0] * (1 - fc) + img[r0, c1] * fc
    bottom = img[r1, c0] * (1 - fc) + img[r1, c1] * fc
    return top * (1 - fr) + bottom * fr
