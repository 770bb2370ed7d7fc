"""Obstacle primitives (box, cylinder, sphere) with poses, and their analytic distances.

Distances are signed: negative inside an obstacle. Poses are ``T_world_obstacle`` (4, 4);
a cylinder's axis is its local z.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from core.errors import PlanningError
from core.transforms import from_xyz_quat, is_rigid, to_xyz_quat

Array = npt.NDArray[np.float64]


def _check_pose(pose: Array, what: str) -> None:
    if not is_rigid(pose):
        raise PlanningError(f"{what}: pose must be a 4x4 rigid transform")


@dataclass(frozen=True)
class Box:
    size: Array  # (3,) full edge lengths (m)
    pose: Array = field(default_factory=lambda: np.eye(4))  # T_world_box, centre of the box

    def __post_init__(self) -> None:
        if np.asarray(self.size).shape != (3,) or np.any(np.asarray(self.size) <= 0):
            raise PlanningError(f"box size must be 3 positive lengths (m), got {self.size}")
        _check_pose(self.pose, "box")


@dataclass(frozen=True)
class Cylinder:
    radius: float  # m
    height: float  # m, along local z, centred
    pose: Array = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        if self.radius <= 0 or self.height <= 0:
            raise PlanningError(
                f"cylinder radius and height must be > 0 m, got {self.radius}, {self.height}"
            )
        _check_pose(self.pose, "cylinder")


@dataclass(frozen=True)
class Sphere:
    radius: float  # m
    center: Array  # (3,) m, world frame

    def __post_init__(self) -> None:
        if self.radius <= 0:
            raise PlanningError(f"sphere radius must be > 0 m, got {self.radius}")


Primitive = Box | Cylinder | Sphere


class PrimitiveWorld:
    """A world of analytic obstacles. ``distance`` is exact and signed."""

    def __init__(self, primitives: list[Primitive] | tuple[Primitive, ...]) -> None:
        self.primitives: tuple[Primitive, ...] = tuple(primitives)
        boxes = [p for p in self.primitives if isinstance(p, Box)]
        cyls = [p for p in self.primitives if isinstance(p, Cylinder)]
        sphs = [p for p in self.primitives if isinstance(p, Sphere)]
        # Inverse poses so that local = R^T (p - t).
        self._box_R = np.stack([b.pose[:3, :3] for b in boxes]) if boxes else np.zeros((0, 3, 3))
        self._box_t = np.stack([b.pose[:3, 3] for b in boxes]) if boxes else np.zeros((0, 3))
        self._box_half = np.stack([b.size / 2 for b in boxes]) if boxes else np.zeros((0, 3))
        self._cyl_R = np.stack([c.pose[:3, :3] for c in cyls]) if cyls else np.zeros((0, 3, 3))
        self._cyl_t = np.stack([c.pose[:3, 3] for c in cyls]) if cyls else np.zeros((0, 3))
        self._cyl_rh = np.array([[c.radius, c.height / 2] for c in cyls]).reshape(-1, 2)
        self._sph_c = np.stack([s.center for s in sphs]) if sphs else np.zeros((0, 3))
        self._sph_r = np.array([s.radius for s in sphs])

    def __len__(self) -> int:
        return len(self.primitives)

    def distance(self, points: Array) -> Array:
        """Signed distance (N,) from points (N, 3) to the nearest obstacle (m); +inf if none.

        Computed on coordinate rows (3, N): numpy's reductions over a short last axis
        (``max(axis=1)`` on (N, 3)) cost more than all the arithmetic (measured 2.5x).
        """
        if points.shape[0] * len(self.primitives) <= 4096:
            return self._distance_few(points)
        out = np.full(points.shape[0], np.inf)
        pts = np.ascontiguousarray(points.T)  # (3, N)
        for R, t, half in zip(self._box_R, self._box_t, self._box_half, strict=True):
            lx, ly, lz = np.abs(R.T @ (pts - t[:, None])) - half[:, None]
            outside = np.sqrt(
                np.maximum(lx, 0.0) ** 2 + np.maximum(ly, 0.0) ** 2 + np.maximum(lz, 0.0) ** 2
            )
            inside = np.minimum(np.maximum(np.maximum(lx, ly), lz), 0.0)
            np.minimum(out, outside + inside, out=out)
        for R, t, (radius, half_h) in zip(self._cyl_R, self._cyl_t, self._cyl_rh, strict=True):
            lx, ly, lz = R.T @ (pts - t[:, None])
            dr = np.sqrt(lx**2 + ly**2) - radius
            dz = np.abs(lz) - half_h
            outside = np.sqrt(np.maximum(dr, 0.0) ** 2 + np.maximum(dz, 0.0) ** 2)
            np.minimum(out, outside + np.minimum(np.maximum(dr, dz), 0.0), out=out)
        for c, radius in zip(self._sph_c, self._sph_r, strict=True):
            d = pts - c[:, None]
            np.minimum(out, np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2) - radius, out=out)
        return out

    def _distance_few(self, points: Array) -> Array:
        """The same distances for few points (one configuration's spheres): all primitives of
        a kind at once, a handful of numpy calls instead of a handful per primitive."""
        out = np.full(points.shape[0], np.inf)
        if len(self._box_t):
            rel = points[None, :, :] - self._box_t[:, None, :]  # (M, N, 3)
            q = np.abs(np.einsum("mnj,mjk->mnk", rel, self._box_R)) - self._box_half[:, None, :]
            d = np.sqrt(np.sum(np.maximum(q, 0.0) ** 2, axis=-1)) + np.minimum(q.max(axis=-1), 0.0)
            np.minimum(out, d.min(axis=0), out=out)
        if len(self._cyl_t):
            rel = points[None, :, :] - self._cyl_t[:, None, :]
            local = np.einsum("mnj,mjk->mnk", rel, self._cyl_R)
            dr = np.hypot(local[..., 0], local[..., 1]) - self._cyl_rh[:, None, 0]
            dz = np.abs(local[..., 2]) - self._cyl_rh[:, None, 1]
            d = np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0)) + np.minimum(
                np.maximum(dr, dz), 0.0
            )
            np.minimum(out, d.min(axis=0), out=out)
        if len(self._sph_c):
            d = np.linalg.norm(points[None] - self._sph_c[:, None], axis=-1) - self._sph_r[:, None]
            np.minimum(out, d.min(axis=0), out=out)
        return out

    def sample_surface(self, n: int, rng: np.random.Generator) -> Array:
        """(n, 3) points on the obstacles' surfaces, spread by area (world frame)."""
        import trimesh

        meshes = [primitive_mesh(p) for p in self.primitives]
        if not meshes:
            raise PlanningError("the world has no obstacles to sample")
        mesh = trimesh.util.concatenate(meshes)
        pts, _ = trimesh.sample.sample_surface(mesh, n, seed=int(rng.integers(2**31)))
        return np.asarray(pts, float)

    # -- serialization -------------------------------------------------------------------

    def to_dict(self) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        for p in self.primitives:
            if isinstance(p, Sphere):
                out.append({"type": "sphere", "radius": p.radius, "center": p.center.tolist()})
                continue
            xyz, quat = to_xyz_quat(p.pose)
            pose = {"xyz": xyz.tolist(), "quat_xyzw": quat.tolist()}
            if isinstance(p, Box):
                out.append({"type": "box", "size": p.size.tolist(), "pose": pose})
            else:
                out.append(
                    {"type": "cylinder", "radius": p.radius, "height": p.height, "pose": pose}
                )
        return out

    @staticmethod
    def from_dict(items: list[dict[str, Any]]) -> PrimitiveWorld:
        prims: list[Primitive] = []
        for i, item in enumerate(items):
            try:
                kind = item["type"]
                if kind == "sphere":
                    prims.append(Sphere(float(item["radius"]), np.asarray(item["center"], float)))
                    continue
                pose_raw = item.get("pose") or {}
                pose = from_xyz_quat(
                    pose_raw.get("xyz", [0, 0, 0]), pose_raw.get("quat_xyzw", [0, 0, 0, 1])
                )
                if kind == "box":
                    prims.append(Box(np.asarray(item["size"], float), pose))
                elif kind == "cylinder":
                    prims.append(Cylinder(float(item["radius"]), float(item["height"]), pose))
                else:
                    raise PlanningError(
                        f"obstacle {i}: unknown type '{kind}'; valid: box, cylinder, sphere"
                    )
            except (KeyError, TypeError, ValueError) as err:
                raise PlanningError(f"obstacle {i} is malformed ({err!r}): {item}") from err
        return PrimitiveWorld(prims)


def primitive_mesh(p: Primitive):  # type: ignore[no-untyped-def]
    """A trimesh of one primitive in the world frame."""
    import trimesh

    if isinstance(p, Box):
        return trimesh.creation.box(extents=p.size, transform=p.pose)
    if isinstance(p, Cylinder):
        return trimesh.creation.cylinder(
            radius=p.radius, height=p.height, transform=p.pose, sections=48
        )
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=p.radius)
    mesh.apply_translation(p.center)
    return mesh
