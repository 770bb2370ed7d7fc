"""Generate a conservative sphere model from a robot's collision meshes.

Why by hand: no maintained Python library builds a *covering* sphere set (cuRobo's and
VAMP's generators need their own stacks; trimesh only gives one bounding sphere per mesh).

The solid link is covered, not just its surface, so that points inside a link cannot slip
between spheres. Coverage is exact for the surface: it is subdivided into small triangles,
every triangle belongs to one sphere, and a ball that contains a triangle's three vertices
contains the whole triangle (balls are convex). The interior is covered on a grid of
``interior_pitch``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import open3d as o3d
import trimesh
from numba import njit
from scipy.cluster.vq import kmeans2

from gaide_core.errors import RobotModelError
from gaide_core.types import Array
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class SpherizeCfg:
    max_spheres: int = 60  # total over all links
    target_overshoot: float = 0.01  # m, stop adding spheres to a link once its skin is thinner
    max_edge: float = 0.02  # m, surface triangles are subdivided to this edge length
    interior_pitch: float = 0.01  # m, grid spacing of interior points that must be covered
    restarts: int = 2  # k-means restarts per (link, k)
    max_per_link: int = 10
    # Links only checked for self-collision (robot config's world_ignored_links) need few.
    max_per_ignored_link: int = 3
    seed: int = 0

    def __post_init__(self) -> None:
        if self.max_spheres < 1:
            raise RobotModelError(f"max_spheres must be >= 1, got {self.max_spheres}")
        if min(self.target_overshoot, self.max_edge, self.interior_pitch) <= 0:
            raise RobotModelError("target_overshoot, max_edge and interior_pitch must be > 0 m")


@dataclass(frozen=True)
class _LinkFit:
    centers: Array  # (k, 3)
    radii: Array  # (k,)
    overshoot: float  # m, 95th percentile of how far the balls' union lies outside the link


class _LinkCoverer:
    """Points that must be covered for one link, and fits of k spheres to them."""

    def __init__(self, mesh: trimesh.Trimesh, cfg: SpherizeCfg) -> None:
        vertices, faces = trimesh.remesh.subdivide_to_size(
            mesh.vertices, mesh.faces, max_edge=cfg.max_edge
        )
        self.tri = np.asarray(vertices, float)[np.asarray(faces)]  # (F, 3, 3)
        lo, hi = mesh.bounds
        axes = [
            np.arange(a, b + cfg.interior_pitch, cfg.interior_pitch)
            for a, b in zip(lo, hi, strict=True)
        ]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(
            o3d.core.Tensor.from_numpy(np.ascontiguousarray(mesh.vertices, np.float32)),
            o3d.core.Tensor.from_numpy(np.ascontiguousarray(mesh.faces, np.uint32)),
        )
        if mesh.is_watertight:
            occupied = self.scene.compute_occupancy(
                o3d.core.Tensor.from_numpy(grid.astype(np.float32))
            )
            inside = occupied.numpy().astype(bool)
        else:
            inside = np.zeros(len(grid), bool)
        self.interior = grid[inside]
        self.mesh = mesh
        self.cfg = cfg

    def fit(self, k: int, rng: np.random.Generator) -> _LinkFit:
        """The better of two partitions into k groups: slabs along the principal axis (near
        optimal for tube-like links) and k-means (for blob-like ones)."""
        centroids = self.tri.mean(axis=1)
        samples = np.concatenate([centroids, self.interior]) if len(self.interior) else centroids
        mean = samples.mean(axis=0)
        axis = np.linalg.svd(samples - mean, full_matrices=False)[2][0]
        s_tri, s_in = (centroids - mean) @ axis, (self.interior - mean) @ axis
        edges = np.linspace(min(s_tri.min(), s_in.min(initial=np.inf)), s_tri.max(), k + 1)
        slabs = (
            np.clip(np.searchsorted(edges, s_tri) - 1, 0, k - 1),
            np.clip(np.searchsorted(edges, s_in) - 1, 0, k - 1),
        )
        candidates = [self._balls(*slabs)]
        if k > 1:
            seeds = self._k_centers(samples, k, rng)
            candidates.append(
                self._balls(_nearest(centroids, seeds), _nearest(self.interior, seeds))
            )
            for _ in range(self.cfg.restarts):
                seeds, _ = kmeans2(samples, k, minit="++", seed=rng, iter=20)
                candidates.append(
                    self._balls(_nearest(centroids, seeds), _nearest(self.interior, seeds))
                )
        return min(candidates, key=lambda f: f.overshoot)

    def _k_centers(self, samples: Array, k: int, rng: np.random.Generator) -> Array:
        """k seeds that shrink the largest group radius: farthest-point seeding, then Lloyd
        steps that move each seed to its group's enclosing-ball centre."""
        seeds = [samples[rng.integers(len(samples))]]
        d2 = np.sum((samples - seeds[0]) ** 2, axis=1)
        for _ in range(k - 1):
            seeds.append(samples[int(np.argmax(d2))])
            d2 = np.minimum(d2, np.sum((samples - seeds[-1]) ** 2, axis=1))
        S = np.asarray(seeds)
        for _ in range(8):
            label = _nearest(samples, S)
            S = np.asarray(
                [
                    _enclosing_center(samples[label == j]) if np.any(label == j) else S[j]
                    for j in range(k)
                ]
            )
        return S

    def _balls(self, tri_label: npt.NDArray[np.int64], in_label: npt.NDArray[np.int64]) -> _LinkFit:
        """One covering ball per label: the triangles' vertices and interior points it owns."""
        centers, radii = [], []
        for j in np.unique(np.concatenate([tri_label, in_label])):
            pts = np.concatenate(
                [self.tri[tri_label == j].reshape(-1, 3), self.interior[in_label == j]]
            )
            c = _enclosing_center(pts)
            centers.append(c)
            radii.append(float(np.sqrt(np.max(np.sum((pts - c) ** 2, axis=1)))))
        C, R = np.asarray(centers), np.asarray(radii)
        return _LinkFit(C, R, self._skin(C, R))

    def _skin(self, C: Array, R: Array) -> float:
        """95th percentile of how far the boundary of the union of balls lies outside the
        link (m): sample each ball's surface, drop points inside another ball, measure."""
        pts = (C[:, None, :] + R[:, None, None] * _DIRECTIONS[None]).reshape(-1, 3)
        owner = np.repeat(np.arange(len(R)), len(_DIRECTIONS))
        d2 = _sqdist(pts, C)
        d2[np.arange(len(pts)), owner] = np.inf
        boundary = pts[np.all(d2 > (R**2)[None, :], axis=1)]
        if len(boundary) == 0:
            return 0.0
        # Open3D's signed distance is negative inside the mesh.
        sd = self.scene.compute_signed_distance(
            o3d.core.Tensor.from_numpy(boundary.astype(np.float32))
        )
        return float(np.mean(np.maximum(sd.numpy().astype(float), 0.0)))


def _nearest(points: Array, seeds: Array) -> npt.NDArray[np.int64]:
    if len(points) == 0:
        return np.zeros(0, np.int64)
    return np.argmin(_sqdist(points, seeds), axis=1)


def _fibonacci_directions(n: int) -> Array:
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5**0.5) * i
    rho = np.sqrt(1.0 - z**2)
    return np.stack([rho * np.cos(phi), rho * np.sin(phi), z], axis=1)


_DIRECTIONS = _fibonacci_directions(48)


def _sqdist(a: Array, b: Array) -> Array:
    return np.sum((a[:, None, :] - b[None, :, :]) ** 2, axis=-1)


@njit(cache=True)
def _enclosing_center(points: Array, iters: int = 200) -> Array:
    """Approximate centre of the minimum enclosing ball (Badoiu-Clarkson iteration); the
    radius is then measured exactly, so coverage never depends on this being optimal.
    Compiled: the fit calls it thousands of times on thousands of points."""
    n = points.shape[0]
    c = np.zeros(3)
    for k in range(n):
        for a in range(3):
            c[a] += points[k, a] / n
    for i in range(1, iters + 1):
        best, far = -1.0, 0
        for k in range(n):
            d = 0.0
            for a in range(3):
                d += (points[k, a] - c[a]) ** 2
            if d > best:
                best, far = d, k
        for a in range(3):
            c[a] += (points[far, a] - c[a]) / (i + 1)
    return c


def generate_spheres(robot: RobotModel, cfg: SpherizeCfg | None = None) -> SphereModel:
    """Cover every link's collision mesh with spheres, spending the sphere budget where the
    balls stick out furthest beyond the link (greedy on the worst overshoot)."""
    cfg = cfg or SpherizeCfg()
    rng = np.random.default_rng(cfg.seed)
    meshes = robot.link_meshes
    if not meshes:
        raise RobotModelError(f"{robot.config.urdf} has no collision geometry to spherize")
    if cfg.max_spheres < len(meshes):
        raise RobotModelError(
            f"max_spheres={cfg.max_spheres} is fewer than the {len(meshes)} links with geometry"
        )
    coverers = {name: _LinkCoverer(mesh, cfg) for name, mesh in meshes.items()}
    # Overshoot is not monotonic in k (k-means and slabs both jump), so allocate on the
    # envelope: a link's fit with k spheres is its best fit with at most k.
    fits = {name: cov.fit(1, rng) for name, cov in coverers.items()}
    frozen: set[str] = set()
    total = len(fits)
    while total < cfg.max_spheres:
        open_links = [n for n in fits if n not in frozen]
        if not open_links:
            break
        worst = max(open_links, key=lambda n: fits[n].overshoot)
        if fits[worst].overshoot <= cfg.target_overshoot:
            break
        k = len(fits[worst].radii)
        cap = (
            cfg.max_per_ignored_link
            if worst in robot.config.world_ignored_links
            else cfg.max_per_link
        )
        better = None
        for extra in range(1, min(cfg.max_spheres - total, cap - k) + 1):
            candidate = coverers[worst].fit(k + extra, rng)
            if candidate.overshoot < fits[worst].overshoot - 1e-4:
                better = candidate
                break
        if better is None:
            frozen.add(worst)
            continue
        total += len(better.radii) - k
        fits[worst] = better
    links = tuple(name for name, f in fits.items() for _ in range(len(f.radii)))
    centers = np.concatenate([f.centers for f in fits.values()])
    radii = np.concatenate([f.radii for f in fits.values()])
    log.info(
        "generated %d spheres; worst overshoot %.1f mm",
        len(radii),
        1e3 * max(f.overshoot for f in fits.values()),
    )
    return SphereModel(links, centers, radii)
