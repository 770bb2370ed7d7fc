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

import numpy as np
import numpy.typing as npt
from scipy import ndimage
from scipy.spatial import cKDTree

from core.errors import PlanningError

Array = npt.NDArray[np.float64]
log = logging.getLogger(__name__)


class CloudWorld:
    """Obstacles given as a point cloud (base/world frame)."""

    def __init__(self, points: Array, voxel: float = 0.01, band: float = 0.3) -> None:
        """points (N, 3) m; voxel: lattice spacing (m); band: distances are exact up to this
        (m) and reported as ``band`` beyond it (a valid lower bound)."""
        pts = np.asarray(points, float)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            raise PlanningError(f"a cloud world needs points of shape (N, 3), N > 0; got {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise PlanningError("the cloud has non-finite points")
        if voxel <= 0 or band <= voxel:
            raise PlanningError(f"need 0 < voxel < band (m), got voxel={voxel}, band={band}")
        self.points = pts
        self.voxel = float(voxel)
        self.band = float(band)
        pad = band + voxel
        self.origin = pts.min(axis=0) - pad
        self.shape = tuple(int(v) for v in np.ceil((pts.max(axis=0) + pad - self.origin) / voxel) + 1)
        occupied = np.zeros(self.shape, bool)
        idx = np.rint((pts - self.origin) / voxel).astype(np.int64)
        occupied[idx[:, 0], idx[:, 1], idx[:, 2]] = True
        # The EDT over occupied lattice points is within voxel*sqrt(3)/2 of the truth: use
        # it only to pick the lattice points whose exact distance is worth computing.
        approx = ndimage.distance_transform_edt(~occupied) * voxel
        near = np.argwhere(approx < band + voxel)
        tree = cKDTree(pts)
        dist, _ = tree.query(self.origin + near * voxel, distance_upper_bound=band, workers=-1)
        field = np.full(self.shape, band, np.float32)
        field[near[:, 0], near[:, 1], near[:, 2]] = np.minimum(dist, band)
        self.field = field
        self._flat = field.ravel()
        self._strides = np.array([self.shape[1] * self.shape[2], self.shape[2], 1], np.int64)
        log.debug("cloud world: %d points, lattice %s, %d exact", len(pts), self.shape, len(near))

    def distance(self, points: Array) -> Array:
        """Lower bound (N,) on the distance (m) from points (N, 3) to the cloud."""
        rel = (points - self.origin) / self.voxel
        idx = np.rint(rel)
        inside = np.all((idx >= 0) & (idx < np.asarray(self.shape)), axis=1)
        lattice = idx.astype(np.int64)
        np.clip(lattice, 0, np.asarray(self.shape) - 1, out=lattice)
        value = self._flat[lattice @ self._strides].astype(float)
        # 1e-6 m also covers the float32 rounding of the stored distances.
        offset = np.linalg.norm(rel - idx, axis=1) * self.voxel + 1e-6
        # Outside the lattice every cloud point is at least the padding (> band) away.
        return np.where(inside, value - offset, self.band)
