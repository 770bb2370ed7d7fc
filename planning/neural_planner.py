"""The neural bidirectional planner (MPNet's Algorithm 1, as the GAIDE paper uses it), with
lazy states contraction, a check of every edge and neural replanning of failing segments.

Beyond the paper: each step draws a batch of stochastic rollouts in one forward pass and takes
the valid proposal (reachable by a valid edge where one is) nearest to the other tree's end;
in ``hybrid`` mode a segment the network cannot repair, or the gap between two trees that
never met, goes to RRT-Connect, so the planner is complete in practice. ``paper`` mode has no
fallback.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.collision import CollisionChecker
from planning.distance_field import CloudWorld
from planning.neural.sampler import Sampler, cached_sampler
from planning.path_ops import pull_string
from planning.planner import PlanResult, PlanStatus, path_length, prepare_plan
from planning.primitives import PrimitiveWorld
from planning.robot_model import RobotModel
from planning.scene_views import surface_cloud

log = logging.getLogger(__name__)

MODES = ("paper", "hybrid")
# Hybrid mode's shortcut attempts on a solved path: the pass takes what contraction between
# the path's own nodes cannot (corners inside an edge, the fallback's detours). On 12 balanced
# test problems per family (shipped weights), median cost TableTop..Shelf III went from
# 5.88/4.66/4.43/7.66/6.13/7.20 rad (none) to 5.53/4.65/4.43/5.48/5.85/5.89 (32) and
# 5.51/4.65/4.43/5.31/5.85/5.73 (96). On the validation split (100 problems a family), 384
# against 96 lowered the mean cost of every family by 0.15-1.9% (Shelf II 6.03 -> 5.91 rad) and
# left fewer paths longer than rrtc's (88 -> 70 of 600), for up to 22% more median planning time
# (docs/results.md, "More shortcut attempts in hybrid mode").
HYBRID_SHORTCUTS = 384
SCENE_POINTS = 2048


def scene_cloud_of(checker: CollisionChecker, seed: int = 0) -> Array:
    """The network's view of the checker's world: surface samples of primitives, or the
    cloud itself (base frame)."""
    world = checker.world
    if isinstance(world, CloudWorld):
        return np.asarray(world.points, float)
    if isinstance(world, PrimitiveWorld):
        if not world.primitives:
            raise PlanningError("the scene has no obstacles: a neural planner needs a scene cloud")
        return surface_cloud(world, SCENE_POINTS, np.random.default_rng(seed))
    raise PlanningError(
        f"a neural planner needs a point cloud or primitives world, not {type(world).__name__}"
    )


@contextlib.contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """torch's intra-op threads set to ``n`` (0: unchanged) inside, restored after."""
    if n <= 0:
        yield
        return
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


class NeuralPlanner:
    """``sampler`` proposes steps (or, given as a checkpoint path, the checkpoint's model,
    loaded for the checker's robot on first use); ``mode`` 'paper' or 'hybrid';
    ``rollouts`` proposals per forward pass; ``max_steps`` of the bidirectional loop per
    (re)plan and ``replans`` rounds of replanning failing segments; ``restart_iterations`` the
    first slice of the hybrid fallback's restarted RRT-Connect (see :meth:`_Run.connect`);
    ``widen`` how far a second draw reaches when no rollout is valid (see
    :meth:`_Run.propose`; 0: no second draw, the paper's sampler); ``widen_blocked`` whether
    that draw is also made when the valid rollouts are all cut off from the tree by
    collisions (see :meth:`_Run.propose`); ``stall_steps`` the steps without the trees'
    gap shrinking after which each tree aims at the other's root (0: never; see
    :meth:`_Run.bidirectional`);
    ``shortcuts``: random shortcut attempts of the compiled shortcut pass
    (:func:`planning.rrtc.shorten`, after vertex reduction) on a solved path (default 0 in
    paper mode, which keeps the paper's lazy states contraction alone; 384 in hybrid mode, so
    its paths are shortened as far as ``rrtc``'s own);
    ``threads`` torch's intra-op threads while planning (0: torch's setting, untouched). One
    is the default: a step's batch is small, and after Open3D or OpenCV have run in the
    process, torch's default thread pool made each forward pass about 20x slower (measured);
    ``kind``: the model a checkpoint must hold (None: any).

    Defaults: 80 steps and 3 rounds in paper mode; 4 steps and 1 round in hybrid mode, where
    the compiled RRT-Connect rooted at the neural trees is the better use of the time after
    that. With OMPL's RRT-Connect, 8 steps solved as many problems as 16 and 40 in less time;
    with the compiled one (tens of ms per shelf problem) 4 steps solved all of 48 problems
    at 39-82 ms median per family against 69-136 ms with 8 (docs/results.md)."""

    def __init__(
        self,
        name: str,
        sampler: Sampler | str | Path,
        *,
        mode: str = "paper",
        rollouts: int = 8,
        max_steps: int | None = None,
        replans: int | None = None,
        restart_iterations: int = 2000,
        # Chosen on the validation split (50 problems per family, paper-mode GAIDE with the
        # earlier weights, trained on 2,038 paths): 3x the rollouts' spread solved
        # 90/78/80/72/42/26% of TableTop/Box/Bins/Shelf I-III, 8x 98/98/88/80/66/50%,
        # 16x 96/96/92/80/74/60% (docs/results.md, "A wider second draw").
        widen: float = 16.0,
        shortcuts: int | None = None,
        widen_blocked: bool = True,
        # Measured on 300 validation problems per shelf family, together with the shorter
        # widened draws of :meth:`_Run._widened_valid`: the mean success over the three
        # shelves went 89.3 -> 91.1% for GAIDE, 87.7 -> 89.9% for SIMPNet and 87.9 -> 87.8%
        # for MPNet (docs/results.md, "Ends that stall on either side of a board").
        stall_steps: int = 10,
        threads: int = 1,
        kind: str | None = None,
    ) -> None:
        if mode not in MODES:
            raise PlanningError(f"mode must be one of {MODES}, got {mode!r}")
        if max_steps is None:
            max_steps = 80 if mode == "paper" else 4
        if replans is None:
            replans = 3 if mode == "paper" else 1
        if shortcuts is None:
            shortcuts = 0 if mode == "paper" else HYBRID_SHORTCUTS
        if (
            min(rollouts, max_steps, restart_iterations) < 1
            or min(replans, threads, shortcuts, stall_steps) < 0
        ):
            raise PlanningError(
                "need rollouts >= 1, max_steps >= 1, replans >= 0, restart_iterations >= 1, "
                f"threads >= 0, shortcuts >= 0, stall_steps >= 0; got {rollouts}, {max_steps}, "
                f"{replans}, {restart_iterations}, {threads}, {shortcuts}, {stall_steps}"
            )
        self.name, self.mode = name, mode
        self._sampler = sampler
        self.rollouts, self.max_steps, self.replans = rollouts, max_steps, replans
        self.restart_iterations, self.threads = restart_iterations, threads
        self.shortcuts = shortcuts
        if not (np.isfinite(widen) and widen >= 0):
            raise PlanningError(f"widen must be a finite factor >= 0, got {widen}")
        self.widen = widen
        self.widen_blocked = widen_blocked
        self.stall_steps = stall_steps
        self.kind = kind

    def plan(
        self,
        checker: CollisionChecker,
        start: Array,
        goal: Array,
        *,
        budget_s: float,
        rng: np.random.Generator,
        cloud: Array | None = None,
    ) -> PlanResult:
        t0 = time.perf_counter()
        start, goal, refused = prepare_plan(self.name, checker, start, goal, t0, budget_s)
        if refused is not None:
            return refused
        run = _Run(self, self.sampler_for(checker.robot), checker, t0 + budget_s, rng)
        if cloud is None:
            cloud = scene_cloud_of(checker, int(rng.integers(2**31)))
        import torch

        with torch_threads(self.threads), torch.random.fork_rng(devices=[]):
            torch.manual_seed(int(rng.integers(2**31)))
            run.scene = run.sampler.scene(cloud)
            status, path, detail = run.solve(start, goal)
        stats = dict(run.stats, encode_and_plan_s=time.perf_counter() - t0)
        return PlanResult(self.name, status, path, time.perf_counter() - t0, detail, stats)

    def sampler_for(self, robot: RobotModel) -> Sampler:
        if isinstance(self._sampler, (str, Path)):
            return cached_sampler(self._sampler, robot, self.kind)
        return self._sampler


class _Timeout(Exception):
    pass


class _Run:
    """One planning call's state: the encoded scene, the deadline, the counters."""

    def __init__(
        self,
        planner: NeuralPlanner,
        sampler: Sampler,
        checker: CollisionChecker,
        deadline: float,
        rng: np.random.Generator,
    ) -> None:
        self.p, self.sampler, self.checker = planner, sampler, checker
        self.deadline, self.rng = deadline, rng
        self.scene: Any = None
        self._gap: tuple[list[Array], list[Array], bool] = ([], [], False)
        self.stats: dict[str, Any] = {
            "forward_passes": 0,
            "proposal_steps": 0,
            "no_valid_rollouts": 0,  # steps where no dropout rollout was valid
            "no_valid_proposals": 0,  # ... nor any of the widened draw (when there is one)
            "no_reachable_proposals": 0,  # valid proposals, none joined to q by a valid edge
            "stalled_steps": 0,  # steps aimed at the other tree's root (see bidirectional)
            "neural_replans": 0,
            "fallback_segments": 0,
            "fallback_restarts": 0,
            "mode": planner.mode,
        }

    def _tick(self) -> None:
        if time.perf_counter() >= self.deadline:
            raise _Timeout

    def solve(self, start: Array, goal: Array) -> tuple[PlanStatus, Array | None, str]:
        status, path, detail = self._solve(start, goal)
        if path is not None and self.p.shortcuts:
            from planning.rrtc import shorten

            t0 = time.perf_counter()
            self.stats["contracted_cost"] = path_length(path)
            path = shorten(self.checker, path, self.rng, self.p.shortcuts)
            self.stats["shorten_s"] = time.perf_counter() - t0
        return status, path, detail

    def _solve(self, start: Array, goal: Array) -> tuple[PlanStatus, Array | None, str]:
        try:
            path = self.bidirectional(start, goal)
            if path is None:
                if self.p.mode == "paper":
                    return (
                        PlanStatus.FAILED,
                        None,
                        (f"the trees did not meet in {self.p.max_steps} steps"),
                    )
                path = self.fallback_gap()
                if path is None:
                    return (
                        PlanStatus.FAILED,
                        None,
                        "the trees did not meet and RRT-Connect stopped without a bridge",
                    )
            path = self.contract(path)
            for _ in range(self.p.replans):
                bad = self.bad_edges(path)
                if not bad.size:
                    return PlanStatus.SUCCESS, path, ""
                self.stats["neural_replans"] += 1
                path = self.contract(self.replan(path, bad, neural=True))
            bad = self.bad_edges(path)
            if bad.size and self.p.mode == "hybrid":
                path = self.contract(self.replan(path, bad, neural=False))
                bad = self.bad_edges(path)
            if bad.size:
                return (
                    PlanStatus.FAILED,
                    None,
                    (f"{bad.size} edges still collide after {self.p.replans} replanning rounds"),
                )
            return PlanStatus.SUCCESS, path, ""
        except _Timeout:
            return (
                PlanStatus.TIMEOUT,
                None,
                (
                    f"no valid path within the budget ({self.stats['forward_passes']} forward passes, "
                    f"{self.stats['neural_replans']} neural replans, {self.stats['fallback_segments']} "
                    "RRT-Connect segments)"
                ),
            )

    # -- the bidirectional loop ------------------------------------------------------------

    def propose(self, q: Array, target: Array) -> Array | None:
        """The next node from ``q`` toward ``target``: the valid rollout nearest the target,
        preferring those joined to ``q`` by a valid edge; None if no rollout is valid.

        Dropout's rollouts lie close together (6-16 deg apart measured on failing Bins
        problems), so when one collides all do. When none is valid and ``widen`` > 0, as
        many proposals are drawn again around their mean with ``widen`` times their own
        spread (per joint, at least a tenth of the step), capped at one step from ``q``.

        With ``widen_blocked``, a widened draw (around the proposals so far) is also made when
        some proposals are valid but no valid edge joins any of them to ``q``, and its
        reachable proposals are taken. Without it, the tree took such a node anyway, the edge
        to it was left to replanning, and replanning a short blocked edge asks the network
        for the same few steps again: the edge still collided after the last round on 23 of
        GAIDE's 31 failures on Shelf III (200 test problems). On the validation split (100 problems a family) paper-mode
        success went from 87.0 / 85.8 / 88.3% to 95.0 / 94.5 / 95.0% for GAIDE / MPNet /
        SIMPNet (docs/results.md, "Valid nodes that the tree cannot reach")."""
        self._tick()
        cands = self.sampler.sample(self.scene, q, target, self.p.rollouts)
        self.stats["forward_passes"] += 1
        self.stats["proposal_steps"] += 1
        ok = self.checker.config_valid(cands)
        if not ok.any():
            self.stats["no_valid_rollouts"] += 1
            if self.p.widen > 0:
                cands, ok = self._widened_valid(q, cands)
            if not ok.any():
                self.stats["no_valid_proposals"] += 1
                return None
        drawn = cands
        cands = cands[ok]
        reach = self._reach(q, cands)
        if not reach.any():
            self.stats["no_reachable_proposals"] += 1
        if not reach.any() and self.p.widen > 0 and self.p.widen_blocked:
            wide = self._widened(q, drawn)
            wide = wide[self.checker.config_valid(wide)]
            wide_reach = self._reach(q, wide) if len(wide) else np.zeros(0, bool)
            if wide_reach.any():
                cands, reach = wide, wide_reach
        pool = cands[reach] if reach.any() else cands
        return pool[int(np.argmin(np.linalg.norm(pool - target, axis=1)))]

    def _reach(self, q: Array, cands: Array) -> np.ndarray:
        """Whether a valid straight edge joins ``q`` to each of ``cands``."""
        return self.checker.edges_valid(np.repeat(q[None], len(cands), axis=0), cands)

    def _widened_valid(self, q: Array, cands: Array) -> tuple[Array, np.ndarray]:
        """The widened draw around ``cands`` and its validity; where none is valid, the same
        draw pulled to half and then a quarter of the way from ``q`` (in a tight spot only
        short moves are free)."""
        full = wide = self._widened(q, cands)
        ok = self.checker.config_valid(wide)
        for share in (0.5, 0.25):
            if ok.any():
                break
            wide = q + share * (full - q)
            ok = self.checker.config_valid(wide)
        return wide, ok

    def _widened(self, q: Array, cands: Array) -> Array:
        step = np.linalg.norm(cands - q, axis=1).max()
        spread = np.maximum(cands.std(axis=0), 0.1 * max(step, 1e-3) / np.sqrt(cands.shape[1]))
        wide = cands.mean(axis=0) + self.p.widen * spread * self.rng.normal(size=cands.shape)
        delta = wide - q
        norm = np.linalg.norm(delta, axis=1, keepdims=True)
        wide = q + delta * np.minimum(1.0, max(step, 1e-3) / np.maximum(norm, 1e-12))
        robot = self.checker.robot
        return np.clip(wide, robot.lower, robot.upper)

    def bidirectional(self, start: Array, goal: Array) -> Array | None:
        """Algorithm 1: grow from both ends by turns until the ends see each other.

        Beyond the paper: after ``stall_steps`` steps in which the gap between the two ends
        did not shrink, the ends stand on either side of an obstacle, each pressing toward
        the other. From then on each tree steps toward the other tree's root (a goal the
        network was trained to route to, around the obstacle) and joins the other tree at
        its deepest node a valid edge reaches."""
        a, b = [start], [goal]
        if self.checker.edge_valid(start, goal):
            return np.stack([start, goal])
        swapped = False
        best, since = np.inf, 0
        for _ in range(self.p.max_steps):
            stalled = 0 < self.p.stall_steps <= since
            nxt = self.propose(a[-1], b[0] if stalled else b[-1])
            if nxt is not None:
                a.append(nxt)
                joined = self._join(nxt, b if stalled else b[-1:])
                if joined is not None:
                    b = b[: joined + 1] if stalled else b
                    fwd, bwd = (b, a) if swapped else (a, b)
                    return np.stack(fwd + bwd[::-1])
            gap = float(np.linalg.norm(a[-1] - b[-1]))
            best, since = (gap, 0) if gap < best - 1e-3 else (best, since + 1)
            if stalled:
                self.stats["stalled_steps"] += 1
            a, b = b, a
            swapped = not swapped
        self._gap = (a, b, swapped)
        return None

    def _join(self, q: Array, nodes: list[Array]) -> int | None:
        """The index of the deepest of ``nodes`` that a valid edge from ``q`` reaches."""
        ok = self._reach(q, np.stack(nodes))
        return int(np.flatnonzero(ok)[-1]) if ok.any() else None

    # -- contraction, checking, replanning -------------------------------------------------

    def contract(self, path: Array) -> Array:
        """Lazy states contraction: from each kept node, jump to the farthest node a valid
        straight edge reaches (:func:`~planning.path_ops.pull_string` with no skip bound),
        within the deadline."""
        return pull_string(path, self.checker, max_skip=None, tick=self._tick)

    def bad_edges(self, path: Array) -> np.ndarray:
        return np.flatnonzero(~self.checker.edges_valid(path[:-1], path[1:]))

    def replan(self, path: Array, bad: np.ndarray, *, neural: bool) -> Array:
        """The path with each failing edge replaced by a neural (or RRT-Connect) segment;
        edges that cannot be repaired are kept for the next round."""
        pieces: list[Array] = []
        prev = 0
        for i in bad:
            pieces.append(path[prev : i + 1])
            seg = (
                self.bidirectional(path[i], path[i + 1])
                if neural
                else self.rrtconnect(path[i], path[i + 1])
            )
            if seg is not None:
                pieces.append(seg[1:-1])
            prev = i + 1
        pieces.append(path[prev:])
        return np.concatenate([p for p in pieces if len(p)])

    def rrtconnect(self, a: Array, b: Array) -> Array | None:
        """A segment from ``a`` to ``b`` by the compiled RRT-Connect (see :meth:`connect`)."""
        res = self.connect(a[None], b[None])
        return None if res is None else res[0]

    def connect(self, starts: Array, goals: Array) -> tuple[Array, int, int] | None:
        """The compiled RRT-Connect (``rrtc``, without its shortcut pass: the neural path is
        contracted as a whole afterwards) from any of ``starts`` to any of ``goals`` with the
        time left: the path and the indices of the start and goal it joins; None if it gave
        up early.

        RRT-Connect's work to solve a shelf problem is heavy-tailed (one seed 0.2 s, another
        over 5 s on the same problem), so it runs in slices of growing length
        (``restart_iterations``, then 1.5x each time; iterations, so the schedule is the same
        on a loaded machine), each a fresh pair of trees with a new seed, until the budget
        ends. Only the first slice has every root; the restarts root the first start and the
        last goal alone: where the first slice failed, the other roots are where the network
        got stuck (on one shelf problem, roots there let 1 seed in 8 through; the bare ends,
        7)."""
        from planning.rrtc import CompiledRRTConnect, RRTCCfg

        self.stats["fallback_segments"] += 1
        iterations = self.p.restart_iterations
        roots = (starts, goals)
        while True:
            left = self.deadline - time.perf_counter()
            if left <= 0.01:
                raise _Timeout
            rrtc = CompiledRRTConnect(RRTCCfg(simplify=False, max_iterations=iterations))
            # the iterations bound the slice; the budget only ends the plan
            res = rrtc.plan_between(self.checker, *roots, budget_s=min(left, 1e9), rng=self.rng)
            if res.path is not None:
                if roots[0] is starts:
                    return res.path, int(res.stats["start_index"]), int(res.stats["goal_index"])
                return res.path, 0, len(goals) - 1
            if res.status is PlanStatus.TIMEOUT:
                raise _Timeout
            self.stats["fallback_restarts"] += 1
            iterations = max(iterations + 1, int(iterations * 1.5))
            roots = (starts[:1], goals[-1:])

    def fallback_gap(self) -> Array | None:
        """Hybrid: RRT-Connect rooted at every node of the two neural trees that the tree's
        root reaches by valid edges (the start tree's nodes as starts, the goal tree's as
        goals, deepest first), so it bridges the trees where they came closest and, failing
        that, joins the start and the goal themselves."""
        a, b, swapped = self._gap
        fwd, bwd = (self._reached(t) for t in ((b, a) if swapped else (a, b)))
        self.stats["fallback_roots"] = [len(fwd), len(bwd)]
        res = self.connect(fwd, bwd[::-1])
        if res is None:
            return None
        bridge, i, k = res
        j = len(bwd) - 1 - k
        return np.concatenate([fwd[: i + 1], bridge[1:-1], bwd[j::-1]])

    def _reached(self, tree: list[Array]) -> Array:
        """The tree's nodes up to its first invalid edge (the root always)."""
        nodes = np.stack(tree)
        bad = np.flatnonzero(~self.checker.edges_valid(nodes[:-1], nodes[1:]))
        return nodes[: bad[0] + 1] if bad.size else nodes
