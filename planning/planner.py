"""What every planner takes and returns, neural or classical.

A planner plans a joint-space path from ``start`` to ``goal`` for a robot whose validity is
decided by a :class:`~planning.collision.CollisionChecker`; it returns a :class:`PlanResult`
with a status, the path (K, dof) and its figures. Start and goal problems (in collision,
outside limits) are statuses, not exceptions: a benchmark counts them.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.collision import CollisionChecker


class PlanStatus(enum.Enum):
    SUCCESS = "success"
    START_INVALID = "start_invalid"  # outside limits or in collision
    GOAL_INVALID = "goal_invalid"
    TIMEOUT = "timeout"  # no path within the budget
    FAILED = "failed"  # the planner gave up before the budget (or crashed on its side)


@dataclass(frozen=True)
class PlanResult:
    planner: str
    status: PlanStatus
    path: Array | None  # (K, dof) rad, start first and goal last; None unless SUCCESS
    time_s: float  # wall time of the call, everything included
    detail: str = ""  # why, for anything but SUCCESS
    stats: dict[str, Any] = field(default_factory=dict)  # planner-specific counters

    @property
    def success(self) -> bool:
        return self.status is PlanStatus.SUCCESS

    @property
    def cost(self) -> float:
        """Joint-space length of the path (rad); inf without a path."""
        return path_length(self.path) if self.path is not None else float("inf")


def path_length(path: Array) -> float:
    """Sum of the Euclidean joint-space lengths of the path's edges (rad)."""
    p = np.asarray(path, float)
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1))) if len(p) > 1 else 0.0


def check_budget(budget_s: float) -> None:
    """PlanningError unless ``budget_s`` is a finite number of seconds > 0."""
    if not (math.isfinite(budget_s) and budget_s > 0):
        raise PlanningError(f"budget_s must be a finite number of seconds > 0, got {budget_s}")


def check_endpoints(
    checker: CollisionChecker, start: Array, goal: Array
) -> tuple[PlanStatus, str] | None:
    """The status for an invalid start or goal (with the checker's diagnosis), else None."""
    for status, q, what in (
        (PlanStatus.START_INVALID, start, "start"),
        (PlanStatus.GOAL_INVALID, goal, "goal"),
    ):
        if checker.config_valid_one(np.ascontiguousarray(q, dtype=float)):
            continue  # the diagnosis (in numpy) is for invalid ones
        diag = checker.diagnose(q)
        if not diag.valid:
            return status, f"{what}: {diag}"
    return None


class Planner(Protocol):
    """A joint-space planner: classical (OMPL), neural (GAIDE, MPNet, ...) or hybrid."""

    name: str

    def plan(
        self,
        checker: CollisionChecker,
        start: Array,
        goal: Array,
        *,
        budget_s: float,
        rng: np.random.Generator,
    ) -> PlanResult: ...
