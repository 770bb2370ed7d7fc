"""What the collision checker needs of a world: distances from points to the obstacles."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from gaide_core.types import Array


class World(Protocol):
    def distance(self, points: Array) -> Array:
        """Lower bound (N,) on the distance (m) from points (N, 3), world frame, to the
        nearest obstacle; negative inside an obstacle where the world knows its inside."""
        ...


class EmptyWorld:
    """No obstacles: only joint limits and self-collision matter."""

    def distance(self, points: Array) -> Array:
        return np.full(points.shape[0], np.inf)
