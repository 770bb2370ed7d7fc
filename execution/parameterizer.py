"""The seam between the pipeline and time parameterization."""

from __future__ import annotations

from typing import Protocol

import numpy.typing as npt

from execution.trajectory import TimedTrajectory
from planning.collision import CollisionChecker


class TimeParameterizer(Protocol):
    """Turns a checked joint path into a timed trajectory that keeps the robot's limits.

    ``path`` is (K, dof) rad; ``checker`` is the collision checker of the scene the path was
    planned in (its robot supplies the limits and joint names). Bad input (a short,
    non-finite or out-of-limit path, a colliding edge, bad limits) raises
    :class:`gaide_core.errors.TimingError`."""

    name: str

    def parameterize(self, path: npt.ArrayLike, checker: CollisionChecker) -> TimedTrajectory: ...
