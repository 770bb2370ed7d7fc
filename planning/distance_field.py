"""A point-cloud world: Euclidean distances on a voxel lattice with O(1) look-ups.

The lattice stores the exact distance from each lattice point to the nearest cloud point
(scipy's k-d tree, inside a band; the band value beyond it). A query rounds to the nearest
lattice point ``v`` and returns ``d(v) - |p - v|``: the distance to a point set is
1-Lipschitz, so this is a *lower bound* on the true distance. Collision checks against it
are conservative (they never call a colliding sphere free) at a cost of at most
``voxel * sqrt(3) / 2`` of clearance.
"""

from __future__ import annotations

import logging
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from gaide_core.errors import PlanningError
from gaide_core.types import Array

log = logging.getLogger(__name__)

# Memory the lattice build holds per cell at its peak: the float32 field, the occupancy
# mask, and scipy's float64 distance transform with its int32 feature indices.
_BYTES_PER_CELL = 4 + 1 + 8 + 12
MAX_LATTICE_BYTES = 4 * 2**30


def _nearest_within(tree: cKDTree, queries: Array, bound: float) -> Array:
    """Distance from each query to the nearest point of ``tree`` (``inf`` beyond ``bound``),
    on all cores.

    Not scipy's own ``workers=-1``: a Ctrl-C while it waits for its threads unwinds past
    them, freeing the tree and the result they still use (a segfault, met when ``gaide demo``
    was interrupted here). These threads are ours and hold what they use; an
    interrupt cancels the chunks not started and waits for the running ones (the k-d tree
    query releases the GIL, so they run in parallel all the same)."""
    chunks = np.array_split(queries, 4 * (os.cpu_count() or 1))
    pool = ThreadPoolExecutor(os.cpu_count())
    try:
        parts = list(pool.map(lambda q: tree.query(q, distance_upper_bound=bound)[0], chunks))
    except BaseException:
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown()
    return np.concatenate(parts) if parts else np.zeros(0)


class CloudWorld:
    """Obstacles given as a point cloud (base/world frame)."""

    def __init__(self, points: Array, voxel: float = 0.01, band: float = 0.15) -> None:
        """points (N, 3) m; voxel: lattice spacing (m); band: distances are exact up to this
        (m) and reported as ``band`` beyond it (a valid lower bound). The band must exceed
        the largest sphere radius + margin + voxel * sqrt(3) for checks to be exact."""
        pts = np.asarray(points, float)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            raise PlanningError(
                f"a cloud world needs points of shape (N, 3), N > 0; got {pts.shape}"
            )
        if not np.all(np.isfinite(pts)):
            raise PlanningError("the cloud has non-finite points")
        if voxel <= 0 or band <= voxel:
            raise PlanningError(f"need 0 < voxel < band (m), got voxel={voxel}, band={band}")
        self.points = pts
        self._tree: cKDTree | None = None  # for exact_distance, built on first use
        self.voxel = float(voxel)
        self.band = float(band)
        pad = band + voxel
        self.origin = pts.min(axis=0) - pad
        self.shape = tuple(
            int(v) for v in np.ceil((pts.max(axis=0) + pad - self.origin) / voxel) + 1
        )
        cells = int(np.prod(np.asarray(self.shape, dtype=np.float64)))
        need = cells * _BYTES_PER_CELL
        if need > MAX_LATTICE_BYTES:  # refused before anything that large is allocated
            extent = pts.max(axis=0) - pts.min(axis=0)
            raise PlanningError(
                f"the distance lattice of a cloud spanning {np.round(extent, 2).tolist()} m at "
                f"a {voxel * 100:g} cm voxel needs about {need / 2**30:.1f} GiB (the largest "
                f"allowed is {MAX_LATTICE_BYTES / 2**30:g} GiB): raise planning.world_voxel or "
                "crop the cloud (perception.workspace_min/max)"
            )
        occupied = np.zeros(self.shape, bool)
        idx = np.rint((pts - self.origin) / voxel).astype(np.int64)
        occupied[idx[:, 0], idx[:, 1], idx[:, 2]] = True
        # The EDT over occupied lattice points is within voxel*sqrt(3)/2 of the truth: use
        # it only to pick the lattice points whose exact distance is worth computing.
        approx = ndimage.distance_transform_edt(~occupied) * voxel
        near = np.argwhere(approx < band + voxel)
        dist = _nearest_within(cKDTree(pts), self.origin + near * voxel, band)
        field = np.full(self.shape, band, np.float32)
        field[near[:, 0], near[:, 1], near[:, 2]] = np.minimum(dist, band)
        self.field = field
        self._flat = field.ravel()
        self._strides = np.array([self.shape[1] * self.shape[2], self.shape[2], 1], np.int64)
        self._shape = np.asarray(self.shape)
        self._inv_voxel = 1.0 / voxel
        self._origin_scaled = self.origin / voxel
        log.debug("cloud world: %d points, lattice %s, %d exact", len(pts), self.shape, len(near))

    def exact_distance(self, points: Array) -> Array:
        """The distance (N,) m from points (N, 3) to the nearest cloud point: the truth that
        :meth:`distance` bounds from below, by a k-d tree (scipy's; built on first use).
        For reports, not for checks: a query costs a tree search, not a look-up."""
        if self._tree is None:
            self._tree = cKDTree(self.points)
        return np.asarray(self._tree.query(np.asarray(points, float).reshape(-1, 3))[0])

    @property
    def exact_up_to(self) -> float:
        """Distances (m) below this are never capped by the band, lattice slack included."""
        return self.band - self.voxel * np.sqrt(3.0)

    def distance(self, points: Array) -> Array:
        """Lower bound (N,) on the distance (m) from points (N, 3) to the cloud.

        Works on coordinate rows (3, N): reductions over numpy's short last axis cost more
        than the arithmetic."""
        rel = np.ascontiguousarray(points.T) * self._inv_voxel - self._origin_scaled[:, None]
        idx = np.rint(rel)
        lx, ly, lz = idx.astype(np.int64)
        sx, sy, sz = self.shape
        inside = (lx >= 0) & (lx < sx) & (ly >= 0) & (ly < sy) & (lz >= 0) & (lz < sz)
        flat = lx * self._strides[0] + ly * self._strides[1] + lz
        np.clip(flat, 0, self._flat.size - 1, out=flat)
        value = self._flat[flat]
        rel -= idx
        # 1e-6 m also covers the float32 rounding of the stored distances.
        offset = np.sqrt(rel[0] ** 2 + rel[1] ** 2 + rel[2] ** 2) * self.voxel + 1e-6
        # Outside the lattice every cloud point is at least the padding (> band) away.
        return np.where(inside, value - offset, self.band)
