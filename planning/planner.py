"""What every planner takes and returns, neural or classical.

A planner plans a joint-space path from ``start`` to ``goal`` for a robot whose validity is
decided by a :class:`~planning.collision.CollisionChecker`; it returns a :class:`PlanResult`
with a status, the path (K, dof) and its figures. Start and goal problems (in collision,
outside limits) are statuses, not exceptions: a benchmark counts them.
"""

from __future__ import annotations

import enum
import math
import time
from collections.abc import Callable
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
    if len(p) < 2:
        return 0.0
    d = p[1:] - p[:-1]  # the sums of np.linalg.norm, at half its cost on a short path
    return float(np.sqrt((d * d).sum(axis=1)).sum())


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


def prepare_plan(
    name: str,
    checker: CollisionChecker,
    start: Array,
    goal: Array,
    t0: float,
    budget_s: float | None = None,
) -> tuple[Array, Array, PlanResult | None]:
    """The prologue every planner's ``plan`` shares: ``budget_s`` checked (PlanningError;
    None: the caller has no clock budget), ``start`` and ``goal`` as (dof,) configurations
    of the checker's robot (errors name them), and, for an invalid one, the
    START_INVALID / GOAL_INVALID result of planner ``name`` timed from ``t0`` (perf_counter
    s); None as the third item when both are valid."""
    if budget_s is not None:
        check_budget(budget_s)
    robot = checker.robot
    start = robot.as_configuration(start, "start")
    goal = robot.as_configuration(goal, "goal")
    bad = check_endpoints(checker, start, goal)
    if bad is None:
        return start, goal, None
    return start, goal, PlanResult(name, bad[0], None, time.perf_counter() - t0, detail=bad[1])


def check_roots(checker: CollisionChecker, starts: Array, goals: Array) -> tuple[Array, Array]:
    """``starts`` (m, dof) and ``goals`` (n, dof) of a ``plan_between`` call as contiguous
    float64 arrays (the compiled kernels take their rows as they are); PlanningError unless
    each is a finite (n >= 1, dof) array. Their validity is the caller's to check."""
    dof = checker.robot.dof
    roots = []
    for what, a in (("starts", starts), ("goals", goals)):
        arr = np.ascontiguousarray(a, float)
        if arr.ndim != 2 or arr.shape[1] != dof or not len(arr) or not np.isfinite(arr).all():
            raise PlanningError(
                f"{what} must be a finite (n >= 1, {dof}) array of configurations, "
                f"got shape {arr.shape}"
            )
        roots.append(arr)
    return roots[0], roots[1]


class MultiRootPlanner:
    """Base of the planners that search from several roots at once (the compiled and the
    OMPL planners): :meth:`plan` checks the budget and the endpoints (invalid ones are
    statuses), :meth:`plan_between` the budget and the roots' shapes, and both hand the
    roots to ``_search`` with the call's start time (perf_counter s) and budget (s)."""

    name: str
    # The subclass's search: (checker, starts, goals, t0, budget_s, rng) -> result.
    _search: Callable[
        [CollisionChecker, Array, Array, float, float, np.random.Generator], PlanResult
    ]

    def plan(
        self,
        checker: CollisionChecker,
        start: Array,
        goal: Array,
        *,
        budget_s: float,
        rng: np.random.Generator,
    ) -> PlanResult:
        """Plan from ``start`` to ``goal`` (dof,) rad within ``budget_s`` seconds of wall time
        (set-up included), with the randomness drawn from ``rng``."""
        t0 = time.perf_counter()
        start, goal, refused = prepare_plan(self.name, checker, start, goal, t0, budget_s)
        if refused is not None:
            return refused
        return self._search(checker, start[None], goal[None], t0, budget_s, rng)

    def plan_between(
        self,
        checker: CollisionChecker,
        starts: Array,
        goals: Array,
        *,
        budget_s: float,
        rng: np.random.Generator,
    ) -> PlanResult:
        """Plan from any of ``starts`` (m, dof) to any of ``goals`` (n, dof) rad, all of them
        valid configurations the caller has checked. The path's first and last rows are one
        start and one goal, exactly; the result's stats name them as ``start_index`` and
        ``goal_index``."""
        t0 = time.perf_counter()
        check_budget(budget_s)
        starts, goals = check_roots(checker, starts, goals)
        return self._search(checker, starts, goals, t0, budget_s, rng)


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
