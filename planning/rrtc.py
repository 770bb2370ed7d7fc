"""``rrtc``: RRT-Connect compiled whole (sampling, nearest neighbour, extend and connect,
certified edges), with a compiled shortcut pass, behind the project's planner protocol.

The search runs in :mod:`planning.compiled.rrtc_kernel` in calls of at most a few hundred
iterations; between calls Python checks the wall-clock budget. Randomness comes from the
caller's generator in blocks of uniform samples that the kernel consumes in order, so the
same seed gives the same path however the calls fall, and a run bounded by iterations
(``max_iterations``) is reproducible on a loaded machine. Shortening
(:mod:`planning.compiled.shortcut_kernel`) is bounded by iterations too.

Whatever checker is given, the kernels check in compiled code; with the numpy reference
checker the same tables are exported from it, so the answers are the same.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.collision import CollisionChecker
from planning.compiled import rrtc_kernel, shortcut_kernel
from planning.compiled.tables import Tables
from planning.planner import MultiRootPlanner, PlanResult, PlanStatus, path_length

_BLOCK = 256  # uniform samples drawn at a time (and iterations per kernel call, at most)
_ROUNDING = 1e-9  # rad: smaller shortcut savings are rounding noise


@dataclass(frozen=True, kw_only=True)
class RRTCCfg:
    # rad, longest extension of a tree toward a sample (joint space). Measured on the task
    # families: 2 rad as fast as 3 with shorter paths, 1.5-2x faster than 0.5 or 1 rad.
    step: float = 2.0
    max_iterations: int = 2_000_000  # extend-connect iterations before giving up
    simplify: bool = True  # shorten the path (vertex reduction and random shortcuts)
    # Random shortcut attempts after vertex reduction: 16-20 shorten the task families' paths
    # by 10-25% for 1.5-2x the planning time; the oracle asks for many more.
    shortcut_iterations: int = 16
    # rad: a random shortcut that saves no more is not certified. A certified edge costs
    # ~30 us, and a saving of 1 mrad (a twentieth of a degree) is nothing on a 5 rad path:
    # with 1e-3 instead of 1e-9, shortening 20 balanced problems per family took up to 27%
    # less time (Box 27%, Shelf III 6%, Shelf I the same) and the paths' summed cost rose by
    # at most 0.004% (docs/results.md).
    min_saving: float = 1e-3
    capacity: int = 1024  # initial nodes per tree (grown as needed)

    def __post_init__(self) -> None:
        if not (self.step > 0 and np.isfinite(self.step)):
            raise PlanningError(f"step must be a finite angle > 0 rad, got {self.step}")
        if self.max_iterations < 1 or self.shortcut_iterations < 0 or self.capacity < 4:
            raise PlanningError(
                "need max_iterations >= 1, shortcut_iterations >= 0, capacity >= 4; got "
                f"{self.max_iterations}, {self.shortcut_iterations}, {self.capacity}"
            )
        if not (0 <= self.min_saving < np.inf):
            raise PlanningError(
                f"min_saving must be a finite angle >= 0 rad, got {self.min_saving}"
            )


def kernel_tables(checker: CollisionChecker) -> Tables:
    """The compiled tables of ``checker``, through its optional ``kernel_tables()`` (see
    :class:`~planning.collision.KernelTablesSource`; made once and kept on a compiled
    checker); PlanningError for a checker without them."""
    # Looked up by name: isinstance against the runtime-checkable protocol costs ~5 us, and
    # a plan asks twice.
    tables = getattr(checker, "kernel_tables", None)
    if tables is None:
        raise PlanningError(
            "the compiled planners need a checker with kernel tables (the sphere checkers), "
            f"not {type(checker).__name__}"
        )
    result: Tables = tables()
    return result


class CompiledRRTConnect(MultiRootPlanner):
    """The ``rrtc`` planner (module docstring), bounded by ``budget_s`` seconds of wall time
    and ``max_iterations`` iterations. With several roots (:meth:`plan_between`), every
    start roots the start tree and every goal the goal tree."""

    name = "rrtc"

    def __init__(self, cfg: RRTCCfg | None = None) -> None:
        self.cfg = cfg or RRTCCfg()

    def __repr__(self) -> str:
        return f"CompiledRRTConnect({self.cfg})"

    def search(
        self, checker: CollisionChecker, start: Array, goal: Array, rng: np.random.Generator
    ) -> PlanResult:
        """Plan between valid ``start`` and ``goal`` (dof,) bounded by ``max_iterations``
        alone, no clock: the same seed gives the same result on any machine, under any
        load (what the training oracle needs)."""
        t0 = time.perf_counter()
        return self._search(checker, start[None], goal[None], t0, None, rng)

    def _search(
        self,
        checker: CollisionChecker,
        starts: Array,
        goals: Array,
        t0: float,
        budget_s: float | None,  # s from t0; None: iterations only
        rng: np.random.Generator,
    ) -> PlanResult:
        cfg = self.cfg
        deadline = None if budget_s is None else t0 + budget_s  # perf_counter time
        I, F, field = kernel_tables(checker).args()  # noqa: E741 (layout names)
        dof = starts.shape[1]
        one = len(starts) == len(goals) == 1
        if one and rrtc_kernel.straight_ok(
            I, F, field, starts[0], goals[0], checker.margin, checker.resolution
        ):
            path = np.stack([starts[0], goals[0]])
            straight: dict[str, Any] = {"iterations": 0, "straight": True}
            straight.update(start_index=0, goal_index=0)
            return PlanResult(
                self.name, PlanStatus.SUCCESS, path, time.perf_counter() - t0, "", straight
            )
        cap = max(cfg.capacity, 2 * (len(starts) + len(goals)))
        nodes = np.zeros((2, cap, dof))
        parents = np.full((2, cap), -1, np.int64)
        sizes = np.array([len(starts), len(goals)], np.int64)
        nodes[0, : len(starts)] = starts
        nodes[1, : len(goals)] = goals
        # the traced path (at most every node of both trees), and room for the shortcut pass
        # to work on it in place
        room = cfg.shortcut_iterations + 2
        traced = np.empty((2 * cap + room, dof))
        out = np.zeros(10, np.int64)
        out[8] = -1  # no connect pending
        block, pos = rng.random((_BLOCK, dof)), 0
        iterations = checks = 0
        joined = False
        while iterations < cfg.max_iterations:
            n = min(_BLOCK - pos, cfg.max_iterations - iterations)
            rrtc_kernel.grow(
                I, F, field, nodes, parents, sizes, block[pos : pos + n], iterations,
                checker.margin, checker.resolution, cfg.step, out, traced,
            )  # fmt: skip
            ran = int(out[1])
            iterations += ran
            checks += int(out[4])
            pos += ran
            if out[0] == rrtc_kernel.JOINED:
                joined = True
                break
            if out[0] == rrtc_kernel.FULL:
                nodes, parents = _grown(nodes, parents)
                traced = np.empty((2 * nodes.shape[1] + room, dof))
            if pos == _BLOCK:
                block, pos = rng.random((_BLOCK, dof)), 0
            if deadline is not None and time.perf_counter() >= deadline:
                break
        solve_s = time.perf_counter() - t0
        stats: dict[str, Any] = {
            "iterations": iterations,
            "edge_checks": checks,
            "tree_sizes": [int(sizes[0]), int(sizes[1])],
            "solve_s": solve_s,
        }
        if not joined:
            if iterations >= cfg.max_iterations:
                detail = f"no path in {iterations} iterations"
                return PlanResult(self.name, PlanStatus.FAILED, None, solve_s, detail, stats)
            assert deadline is not None
            detail = f"no path in {deadline - t0:.3f} s ({iterations} iterations)"
            return PlanResult(self.name, PlanStatus.TIMEOUT, None, solve_s, detail, stats)
        K = int(out[5])
        stats.update(start_index=int(out[6]), goal_index=int(out[7]), raw_waypoints=K)
        if cfg.simplify:
            path, stats["raw_cost"] = _shorten_rows(
                checker, traced, K, rng, cfg.shortcut_iterations, cfg.min_saving
            )
            stats["simplify_s"] = time.perf_counter() - t0 - solve_s
        else:
            path = traced[:K].copy()
            stats["raw_cost"] = path_length(path)
        return PlanResult(self.name, PlanStatus.SUCCESS, path, time.perf_counter() - t0, "", stats)


def shorten(
    checker: CollisionChecker,
    path: Array,
    rng: np.random.Generator,
    iterations: int,
    min_saving: float = _ROUNDING,
) -> Array:
    """``path`` (K, dof), every edge certified, shortened by the compiled shortcut pass:
    vertex reduction, ``iterations`` random shortcuts (their arc-length pairs drawn from
    ``rng``; one saving ``min_saving`` rad or less is not tried), vertex reduction. Same
    first and last rows, never longer, every edge certified (the input itself where the
    pass could not certify the pieces it kept: measured, 0 of 2,400 oracle passes on 240
    training problems, where 49 pieces stayed and passed)."""
    K = len(path)
    rows = np.empty((K + iterations + 2, path.shape[1]))
    rows[:K] = path
    return _shorten_rows(checker, rows, K, rng, iterations, min_saving)[0]


def _shorten_rows(
    checker: CollisionChecker,
    rows: Array,
    K: int,
    rng: np.random.Generator,
    iterations: int,
    min_saving: float,
) -> tuple[Array, float]:
    """:func:`shorten` on the path ``rows[:K]``, in place (``rows`` has at least K +
    iterations + 2 rows); the shortened path (a copy) and the input's length (rad)."""
    I, F, field = kernel_tables(checker).args()  # noqa: E741 (layout names)
    inherited = np.zeros(len(rows), bool)
    report, lengths = np.zeros(2, np.int64), np.zeros(2)
    k = shortcut_kernel.shorten(
        I, F, field, rows, inherited, K, rng.random((iterations, 2)), checker.margin,
        checker.resolution, min_saving, report, lengths,
    )  # fmt: skip
    return rows[:k].copy(), float(lengths[0])


def _grown(nodes: Array, parents: np.ndarray) -> tuple[Array, np.ndarray]:
    """The tree arrays with twice the capacity (the nodes kept)."""
    cap = nodes.shape[1]
    n2 = np.zeros((2, 2 * cap, nodes.shape[2]))
    p2 = np.full((2, 2 * cap), -1, np.int64)
    n2[:, :cap] = nodes
    p2[:, :cap] = parents
    return n2, p2
