"""The training oracle: the shortest path strong classical planners find under a generous
budget, resampled to a fixed step, and a measure of how close to the best known it is.

:func:`oracle_path` spends its budget in two phases: several RRT-Connect runs, each shortcut
to convergence (fast, often near-optimal in uncluttered scenes), then AORRTC (asymptotically
optimal) for the rest, also shortcut. The shortest candidate whose resampled path passes the
checker wins. :func:`oracle_quality` compares its cost against the best of several long
anytime runs.
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any

import numpy as np

from core.errors import PlanningError
from planning.collision import CollisionChecker
from planning.ompl_planners import ANYTIME_PLANNERS, OmplPlanner
from planning.planner import (
    Array,
    PlanResult,
    PlanStatus,
    check_budget,
    check_endpoints,
    path_length,
)
from planning.shortcut import resample, shortcut

log = logging.getLogger(__name__)

# Budget shares: RRT-Connect runs with their shortcutting, then AORRTC; the rest is kept for
# shortcutting AORRTC's path and resampling.
_CONNECT_SHARE = 0.4
_ANYTIME_SHARE = 0.5
# Shortcutting "to convergence": stop after this many batched rounds without a gain.
_SHORTCUT_ITERATIONS = 4000
_SHORTCUT_PATIENCE = 12


def _refine(
    path: Array, checker: CollisionChecker, rng: np.random.Generator, deadline: float
) -> Array:
    """``path`` shortcut until it stops improving or the deadline passes."""
    return shortcut(
        path,
        checker,
        rng,
        iterations=_SHORTCUT_ITERATIONS,
        patience=_SHORTCUT_PATIENCE,
        budget_s=max(deadline - time.perf_counter(), 1e-3),
    )


def oracle_path(
    checker: CollisionChecker,
    start: Array,
    goal: Array,
    rng: np.random.Generator,
    *,
    budget_s: float = 10.0,
    max_step: float = 0.05,
    connect_runs: int = 4,
    rescue_s: float = 0.0,
) -> PlanResult:
    """The best path found from ``start`` to ``goal`` (dof,) rad in about ``budget_s``
    seconds, resampled so that no step exceeds ``max_step`` rad.

    Returns a :class:`PlanResult` named ``oracle``: SUCCESS with the path (K, dof), start
    and goal exact; START_INVALID / GOAL_INVALID; TIMEOUT when no planner found a path in
    time; FAILED when a planner failed otherwise and none succeeded, or when no candidate's
    resampled path passes the checker. When neither phase found a path, RRT-Connect gets up
    to ``rescue_s`` more seconds (hard problems would otherwise be missing from training
    data, biasing it toward easy ones). ``stats`` holds every candidate's source and cost
    (rad), every planner run's outcome, the winner, and the cost before resampling.
    """
    t0 = time.perf_counter()
    check_budget(budget_s)
    if connect_runs < 0:
        raise PlanningError(f"connect_runs must be >= 0, got {connect_runs}")
    start = checker.robot.as_configuration(start, "start")
    goal = checker.robot.as_configuration(goal, "goal")
    bad = check_endpoints(checker, start, goal)
    if bad is not None:
        return PlanResult("oracle", bad[0], None, time.perf_counter() - t0, detail=bad[1])
    deadline = t0 + budget_s
    candidates: list[tuple[str, Array]] = []
    runs: list[tuple[str, str, str]] = []  # (planner, status, detail) of every planner run

    connect_deadline = t0 + _CONNECT_SHARE * budget_s
    rrtc = OmplPlanner("rrtconnect")
    for run in range(connect_runs):
        left = connect_deadline - time.perf_counter()
        if left <= 0:
            break
        res = rrtc.plan(checker, start, goal, budget_s=left, rng=rng)
        runs.append((res.planner, res.status.value, res.detail))
        if res.path is None:
            break  # RRT-Connect used its whole share: another run would get no time
        candidates.append((f"rrtconnect#{run}", _refine(res.path, checker, rng, connect_deadline)))

    # AORRTC's share ends at a fixed point of the budget; if the RRT-Connect phase ran over,
    # it still gets a tenth of the budget.
    anytime_end = t0 + (_CONNECT_SHARE + _ANYTIME_SHARE) * budget_s
    anytime_s = max(anytime_end - time.perf_counter(), 0.1 * budget_s)
    res = OmplPlanner("aorrtc").plan(checker, start, goal, budget_s=anytime_s, rng=rng)
    runs.append((res.planner, res.status.value, res.detail))
    if res.path is not None:
        candidates.append(("aorrtc", _refine(res.path, checker, rng, deadline)))

    if not candidates and rescue_s > 0:
        res = rrtc.plan(checker, start, goal, budget_s=rescue_s, rng=rng)
        runs.append(("rrtconnect-rescue", res.status.value, res.detail))
        if res.path is not None:
            rescue_end = time.perf_counter() + 0.25 * budget_s
            candidates.append(("rrtconnect-rescue", _refine(res.path, checker, rng, rescue_end)))

    stats: dict[str, Any] = {
        "candidates": [(src, path_length(p)) for src, p in candidates],
        "runs": runs,
    }
    if not candidates:
        failed = [r for r in runs if r[1] != PlanStatus.TIMEOUT.value]
        return PlanResult(
            "oracle",
            PlanStatus.FAILED if failed else PlanStatus.TIMEOUT,
            None,
            time.perf_counter() - t0,
            detail=f"no planner found a path in {budget_s + rescue_s:.3f} s"
            + "".join(f"; {name}: {detail}" for name, _, detail in failed),
            stats=stats,
        )
    for src, path in sorted(candidates, key=lambda c: path_length(c[1])):
        dense = resample(path, max_step)
        bad_edge = checker.first_invalid_edge(dense)
        if bad_edge is None:
            stats.update(winner=src, cost_before_resample=path_length(path))
            log.debug("oracle: %s wins with %.4f rad", src, path_length(path))
            return PlanResult(
                "oracle", PlanStatus.SUCCESS, dense, time.perf_counter() - t0, stats=stats
            )
        # A sub-edge of a valid edge is sampled differently and can miss the margin.
        log.warning("oracle: resampled %s path fails at edge %d; trying the next", src, bad_edge)
    return PlanResult(
        "oracle",
        PlanStatus.FAILED,
        None,
        time.perf_counter() - t0,
        detail="no candidate's resampled path passes the checker",
        stats=stats,
    )


def oracle_quality(
    checker: CollisionChecker,
    start: Array,
    goal: Array,
    rng: np.random.Generator,
    *,
    budget_s: float = 10.0,
    max_step: float = 0.05,
    reference_runs: int = 3,
    reference_factor: float = 3.0,
    reference_planners: tuple[str, ...] = ("aorrtc", "bitstar"),
) -> dict[str, Any]:
    """The oracle's cost on one problem against the best of ``reference_runs`` long runs of
    anytime planners (cycling through ``reference_planners``), each given
    ``reference_factor`` x ``budget_s`` seconds and shortcut like the oracle's candidates, so
    the ratio measures the search rather than the post-processing.

    Returns ``oracle_cost`` and ``reference_cost`` (rad, inf without a path), ``ratio``
    (oracle / reference; nan unless both are finite; below 1 when the oracle wins),
    ``reference_costs`` per run, ``oracle_status`` and the wall times (s).
    """
    if reference_runs < 1 or not reference_factor > 0:
        raise PlanningError(
            f"need reference_runs >= 1 and reference_factor > 0; got {reference_runs}, "
            f"{reference_factor}"
        )
    unknown = [p for p in reference_planners if p not in ANYTIME_PLANNERS]
    if unknown or not reference_planners:
        raise PlanningError(
            f"reference planners must be anytime planners, among {sorted(ANYTIME_PLANNERS)}; "
            f"got {list(reference_planners)}"
        )
    oracle = oracle_path(checker, start, goal, rng, budget_s=budget_s, max_step=max_step)
    t0 = time.perf_counter()
    costs: list[tuple[str, float]] = []
    for run in range(reference_runs):
        name = reference_planners[run % len(reference_planners)]
        res = OmplPlanner(name).plan(
            checker, start, goal, budget_s=reference_factor * budget_s, rng=rng
        )
        cost = math.inf
        if res.path is not None:
            refined = shortcut(
                res.path,
                checker,
                rng,
                iterations=_SHORTCUT_ITERATIONS,
                patience=_SHORTCUT_PATIENCE,
            )
            cost = path_length(refined)
        costs.append((name, cost))
    reference = min(c for _, c in costs)
    both = math.isfinite(oracle.cost) and math.isfinite(reference) and reference > 0
    return {
        "oracle_cost": oracle.cost,
        "reference_cost": reference,
        "ratio": oracle.cost / reference if both else math.nan,
        "reference_costs": costs,
        "oracle_status": oracle.status.value,
        "oracle_time_s": oracle.time_s,
        "reference_time_s": time.perf_counter() - t0,
    }
