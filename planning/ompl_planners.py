"""OMPL's geometric planners behind the project's :class:`~planning.planner.Planner` protocol.

``rrtconnect`` (the paper's Bi-RRT) stops at its first solution; ``rrtstar``,
``informed_rrtstar``, ``bitstar`` and ``aorrtc`` are anytime and use the whole budget: the
path-length objective gets a cost threshold of 0 rad, which no path reaches, so only the
budget ends them.

OMPL sees the project's checker twice: as the state validity checker (one configuration per
call) and as the motion validator (one straight joint-space edge per call, certified by
:meth:`~planning.collision.CollisionChecker.edges_valid`), each one compiled call with the
default checker. OMPL's own discrete motion checking is never used, so a path OMPL accepts is
a path the project's checker certifies. The budget is enforced by the
termination condition and, for planners that check it only between long inner loops, by the
callbacks, which refuse every state and motion once the budget is spent.

Randomness: OMPL has one process-wide seed generator from which every OMPL random generator
takes its seed when it is created. :meth:`OmplPlanner.plan` reseeds it from the caller's
generator before it creates anything, so a call is reproducible as far as OMPL is: RRT-Connect
returns the same path for the same seed; an anytime planner finds the same first solution,
but how far it improves it depends on how many iterations fit in the (wall-clock) budget.
Plans running concurrently in threads of one process share the seed generator and are not
reproducible.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.collision import CollisionChecker
from planning.path_ops import repair
from planning.planner import MultiRootPlanner, PlanResult, PlanStatus

log = logging.getLogger(__name__)

#: Planner name -> OMPL geometric planner class name.
_OMPL_CLASSES = {
    "rrtconnect": "RRTConnect",
    "rrtstar": "RRTstar",
    "informed_rrtstar": "InformedRRTstar",
    "bitstar": "BITstar",
    "aorrtc": "AORRTC",
}
PLANNER_NAMES: tuple[str, ...] = tuple(_OMPL_CLASSES)
#: The asymptotically optimal planners, which refine their solution until the budget ends.
ANYTIME_PLANNERS: frozenset[str] = frozenset(PLANNER_NAMES) - {"rrtconnect"}

# Share of the budget an anytime planner leaves to the path simplifier when simplify=True
# (RRT-Connect leaves whatever it did not use).
_SIMPLIFY_SHARE = 0.1
# Largest distance (rad) OMPL's solution may end from the requested start or goal: OMPL's
# goal test is exact up to machine epsilon, so anything larger means a wrong solution.
_ENDPOINT_TOL = 1e-6


def make_ompl_planner(name: str, *, simplify: bool = False) -> OmplPlanner:
    """The OMPL planner called ``name`` (one of :data:`PLANNER_NAMES`)."""
    return OmplPlanner(name, simplify=simplify)


@dataclass
class _Counters:
    """What the callbacks count during one plan call."""

    validity_calls: int = 0
    validity_time_s: float = 0.0  # s inside the state validity callback
    motion_checks: int = 0
    invalid_motions: int = 0
    motion_time_s: float = 0.0  # s inside the motion validator
    first_solution_s: float | None = None  # s from the start of the call
    first_solution_cost: float | None = None  # rad
    cost_trace: list[tuple[float, float]] = field(default_factory=list)  # (s, rad)
    expired: bool = False  # the budget ended the solve
    # Some planners (AORRTC) consult their termination condition only between long inner
    # loops; after this perf_counter time the callbacks refuse every state and motion, so
    # that the solve returns promptly. None while no solve runs.
    cutoff: float | None = None
    refused: int = 0  # states and motions refused after the cutoff

    def refuse(self) -> bool:
        """Count a refusal past the cutoff; returns False (invalid) for the callback."""
        if not self.refused:
            # Planners and OMPL's path simplifier warn about the refused motions they meet
            # (e.g. "Solution path may slightly touch on an invalid region"): expected now.
            # The plan call restores the level.
            ou.setLogLevel(ou.LogLevel.LOG_ERROR)
        self.refused += 1
        return False


class _EdgeValidator(ob.MotionValidator):  # type: ignore[misc]
    """OMPL motion validator: one straight joint-space edge through ``edges_valid``."""

    def __init__(self, si: Any, checker: CollisionChecker, dof: int, counters: _Counters) -> None:
        super().__init__(si)
        self._checker = checker
        self._q0 = np.zeros(dof)
        self._q1 = np.zeros(dof)
        self._dims = range(dof)
        self._counters = counters

    def checkMotion(self, s1: Any, s2: Any) -> bool:
        t = time.perf_counter()
        c = self._counters
        if c.cutoff is not None and t > c.cutoff:
            return c.refuse()
        q0, q1 = self._q0, self._q1
        for i in self._dims:
            q0[i] = s1[i]
            q1[i] = s2[i]
        ok = self._checker.edge_valid_one(q0, q1)
        c.motion_checks += 1
        c.invalid_motions += not ok
        c.motion_time_s += time.perf_counter() - t
        return ok


def _validity_callback(
    checker: CollisionChecker, dof: int, counters: _Counters
) -> Callable[[Any], bool]:
    """OMPL state validity callback: one configuration, in a reused (dof,) buffer, one
    compiled call."""
    row = np.zeros(dof)
    dims = range(dof)

    def valid(state: Any) -> bool:
        t = time.perf_counter()
        if counters.cutoff is not None and t > counters.cutoff:
            return counters.refuse()
        for i in dims:
            row[i] = state[i]
        ok = checker.config_valid_one(row)
        counters.validity_calls += 1
        counters.validity_time_s += time.perf_counter() - t
        return ok

    return valid


@contextlib.contextmanager
def _ompl_log_level(level: Any) -> Iterator[None]:
    """OMPL's (process-wide) log level at most as verbose as ``level`` for the block (a caller
    that silenced OMPL, such as the harness, stays silent), then restored."""
    previous = ou.getLogLevel()
    ou.setLogLevel(level if level.value > previous.value else previous)
    try:
        yield
    finally:
        ou.setLogLevel(previous)


def _seed_ompl(seed: int) -> None:
    """Reseed OMPL's seed generator. OMPL logs an error when generators already exist (it
    cannot reseed those); every generator a plan call uses is created after this, so the
    message does not apply here and is silenced."""
    with _ompl_log_level(ou.LogLevel.LOG_NONE):
        ou.RNG.setSeed(seed)


def _state(space: Any, q: Array) -> Any:
    s = space.allocState()
    for i, v in enumerate(q):
        s[i] = float(v)
    return s


def _ompl_problem(
    checker: CollisionChecker, starts: Array, goals: Array, counters: _Counters
) -> tuple[Any, Any, Any, _EdgeValidator]:
    """OMPL's space information (the joint box, the checker as state and motion validity,
    counted in ``counters``), the problem (every start, every goal), its path-length
    objective, whose threshold of 0 rad no path meets (anytime planners use their whole
    budget), and the motion validator, for the caller to hold while OMPL uses it."""
    robot = checker.robot
    dof = robot.dof
    space = ob.RealVectorStateSpace(dof)
    bounds = ob.RealVectorBounds(dof)
    for i in range(dof):
        bounds.setLow(i, float(robot.lower[i]))
        bounds.setHigh(i, float(robot.upper[i]))
    space.setBounds(bounds)
    si = ob.SpaceInformation(space)
    si.setStateValidityChecker(_validity_callback(checker, dof, counters))
    validator = _EdgeValidator(si, checker, dof, counters)
    si.setMotionValidator(validator)
    si.setup()
    pdef = ob.ProblemDefinition(si)
    for q in starts:
        pdef.addStartState(_state(space, q))
    if len(goals) == 1:
        pdef.setGoalState(_state(space, goals[0]))
    else:
        goal_states = ob.GoalStates(si)
        for q in goals:
            goal_states.addState(_state(space, q))
        pdef.setGoal(goal_states)
    objective = ob.PathLengthOptimizationObjective(si)
    objective.setCostThreshold(ob.Cost(0.0))
    pdef.setOptimizationObjective(objective)
    return si, pdef, objective, validator


def _path_array(path: Any, dof: int) -> Array:
    """(K, dof) rad from an OMPL PathGeometric."""
    out = np.empty((path.getStateCount(), dof))
    for k in range(out.shape[0]):
        s = path.getState(k)
        out[k] = [s[i] for i in range(dof)]
    return out


class OmplPlanner(MultiRootPlanner):
    """One of OMPL's geometric planners (see :data:`PLANNER_NAMES`) as a project planner.
    OMPL's seed is drawn from the plan call's generator. With several roots
    (:meth:`plan_between`), OMPL roots a start tree at every start and adds the goals as
    goal-tree roots as its goal tree grows (RRT-Connect).

    ``simplify``: run OMPL's PathSimplifier (shortcutting and vertex reduction) on the
    solution within the budget; anytime planners then stop their search at 90 % of it.
    """

    def __init__(self, name: str, *, simplify: bool = False) -> None:
        if name not in _OMPL_CLASSES:
            raise PlanningError(f"unknown OMPL planner '{name}'; valid: {list(PLANNER_NAMES)}")
        self.name = name
        self.simplify = simplify
        self.anytime = name in ANYTIME_PLANNERS

    def __repr__(self) -> str:
        return f"OmplPlanner({self.name!r}, simplify={self.simplify})"

    def _search(
        self,
        checker: CollisionChecker,
        starts: Array,
        goals: Array,
        t0: float,
        budget_s: float,
        rng: np.random.Generator,
    ) -> PlanResult:
        seed = int(rng.integers(1, 2**31 - 1))
        with _ompl_log_level(ou.LogLevel.LOG_WARN):
            status, path, detail, stats = self._solve(checker, starts, goals, t0, budget_s, seed)
        elapsed = time.perf_counter() - t0
        log.debug(
            "%s: %s in %.3f s (budget %.3f s), %d motion checks",
            self.name,
            status.value,
            elapsed,
            budget_s,
            stats["motion_checks"],
        )
        return PlanResult(self.name, status, path, elapsed, detail=detail, stats=stats)

    def _solve(
        self,
        checker: CollisionChecker,
        starts: Array,
        goals: Array,
        t0: float,
        budget_s: float,
        seed: int,
    ) -> tuple[PlanStatus, Array | None, str, dict[str, Any]]:
        dof = checker.robot.dof
        deadline = t0 + budget_s
        solve_deadline = deadline
        if self.simplify and self.anytime:
            solve_deadline = t0 + (1.0 - _SIMPLIFY_SHARE) * budget_s
        _seed_ompl(seed)
        counters = _Counters()
        # held while OMPL may call it: its C++ side points at this Python object
        si, pdef, objective, _validator = _ompl_problem(checker, starts, goals, counters)
        planner = getattr(og, _OMPL_CLASSES[self.name])(si)
        planner.setProblemDefinition(pdef)
        planner.setup()

        # Read through a holder that is emptied after the solve: AORRTC keeps its termination
        # condition, and a closure holding the planner would make a reference cycle through
        # C++ that Python cannot collect.
        best_cost: list[Callable[[], Any]] = [planner.bestCost] if self.anytime else []

        def terminate() -> bool:
            # Evaluated by the planner once per iteration: it records the anytime planners'
            # progress (which OMPL's Python bindings give no callback for) and ends the solve.
            now = time.perf_counter()
            if best_cost:
                cost = float(best_cost[0]().value())
                trace = counters.cost_trace
                if math.isfinite(cost) and (not trace or cost < trace[-1][1]):
                    if not trace:
                        counters.first_solution_s = now - t0
                        counters.first_solution_cost = cost
                    trace.append((now - t0, cost))
            if now >= solve_deadline:
                counters.expired = True
                return True
            return False

        counters.cutoff = solve_deadline
        ompl_status = planner.solve(ob.PlannerTerminationCondition(terminate))
        counters.cutoff = None
        best_cost.clear()
        solved_at = time.perf_counter()
        stats: dict[str, Any] = {
            "seed": seed,
            "ompl_status": ompl_status.asString(),
            "solve_s": solved_at - t0,
            "solve_budget_s": solve_deadline - t0,  # the search's share of the budget
        }
        exact = (
            ompl_status.getStatus() == ob.PlannerStatus.EXACT_SOLUTION and pdef.hasExactSolution()
        )
        path: Array | None = None
        raw_path: Array | None = None  # OMPL's own solution, before our simplify pass
        if exact:
            solution = og.PathGeometric(pdef.getSolutionPath())
            stats["raw_cost"] = float(solution.length())
            stats["raw_waypoints"] = int(solution.getStateCount())
            if not self.anytime:
                counters.first_solution_s = solved_at - t0
                counters.first_solution_cost = stats["raw_cost"]
            if self.simplify:
                remaining = deadline - time.perf_counter()
                simplifier = og.PathSimplifier(si, pdef.getGoal(), objective)
                raw = og.PathGeometric(solution)
                if remaining > 0:
                    simplifier.simplify(solution, remaining, False)
                stats["simplify_s"] = time.perf_counter() - solved_at
                # The simplifier's B-spline smoothing and a cut-short pass can leave a longer
                # path than it was given: keep whichever is shorter.
                if solution.length() > raw.length():
                    solution = raw
                    stats["simplify_kept_raw"] = True
                else:
                    raw_path = _path_array(raw, dof)
            path = _path_array(solution, dof)
        elif (
            self.name == "aorrtc"
            and ompl_status.getStatus() == ob.PlannerStatus.INVALID_GOAL
            and len(starts) == len(goals) == 1
            and checker.edge_valid(starts[0], goals[0])
        ):
            # OMPL's AORRTC (2.0) shortcuts its solution to the straight start-goal edge when
            # that edge is free, then rejects that 2-state path as "zero-length" and reports
            # an invalid goal (the ends passed prepare_plan's check, so the goal is valid). The
            # path it had is the straight edge, checked here again.
            path = np.stack([starts[0], goals[0]])
            stats["raw_cost"] = float(np.linalg.norm(goals[0] - starts[0]))
            stats["straight_edge_workaround"] = True
        elif pdef.hasApproximateSolution():
            stats["approximate_gap"] = float(pdef.getSolutionDifference())  # rad from goal
        stats.update(
            validity_calls=counters.validity_calls,
            validity_time_s=counters.validity_time_s,
            motion_checks=counters.motion_checks,
            invalid_motions=counters.invalid_motions,
            motion_time_s=counters.motion_time_s,
            refused_after_budget=counters.refused,
            first_solution_s=counters.first_solution_s,
            first_solution_cost=counters.first_solution_cost,
        )
        if self.anytime:
            stats["cost_trace"] = counters.cost_trace
        if hasattr(planner, "numIterations"):
            stats["iterations"] = int(planner.numIterations())

        if path is None:
            if counters.expired or solved_at >= solve_deadline:
                return PlanStatus.TIMEOUT, None, f"no exact solution in {budget_s:.3f} s", stats
            return (
                PlanStatus.FAILED,
                None,
                f"OMPL {self.name} stopped early: {stats['ompl_status']}",
                stats,
            )
        status, final, detail, stats = self._finish(checker, path, starts, goals, stats)
        if final is None and raw_path is not None:
            # The simplifier inserts waypoints on edges it checked and does not check the
            # pieces again, so its path can hold an edge that repair cannot fix. The search's
            # own solution, every edge of it checked by our motion validator, still stands.
            stats["simplify_rejected"] = detail
            stats["simplify_kept_raw"] = True
            status, final, detail, stats = self._finish(checker, raw_path, starts, goals, stats)
        return status, final, detail, stats

    def _finish(
        self,
        checker: CollisionChecker,
        path: Array,
        starts: Array,
        goals: Array,
        stats: dict[str, Any],
    ) -> tuple[PlanStatus, Array | None, str, dict[str, Any]]:
        """The solution with its ends set to the exact inputs it joins, checked once more
        (and repaired where it can be). ``path`` is modified in place."""
        d_start = np.linalg.norm(starts - path[0], axis=1)
        d_goal = np.linalg.norm(goals - path[-1], axis=1)
        i, j = int(np.argmin(d_start)), int(np.argmin(d_goal))
        gap = max(float(d_start[i]), float(d_goal[j]))
        if len(path) == 1:  # start == goal: OMPL's path is the one state
            path = np.concatenate([path, path])
        if gap > _ENDPOINT_TOL:
            return PlanStatus.FAILED, None, f"OMPL's path ends {gap:.3g} rad off", stats
        path[0], path[-1] = starts[i], goals[j]
        stats["start_index"], stats["goal_index"] = i, j
        path, repaired, bad = repair(path, checker)
        stats["repaired_edges"] = repaired
        if bad is not None:
            return (
                PlanStatus.FAILED,
                None,
                f"OMPL's path has edge {bad} that the checker rejects",
                stats,
            )
        return PlanStatus.SUCCESS, path, "", stats
