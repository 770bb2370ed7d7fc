"""The benchmark harness: every planner on the same problems, each returned path checked by
the harness itself, the paper's Table I figures (T, C, S) per family and planner.

Runs over a process pool (both cores busy), deterministic per problem seed: a run's
randomness comes from (problem seed, planner name) only.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import time
import zlib
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from gaide_core.errors import PlanningError
from planning.collision import CollisionChecker
from planning.families import generate_problem
from planning.family_names import CATEGORIES, FAMILIES, split_seed
from planning.path_check import check_path
from planning.planner import Planner, PlanResult, PlanStatus, check_endpoints
from planning.problem import Problem, load_problems, problem_from_dict
from planning.registry import is_neural, make_planner, planner_names
from planning.robot_model import RobotModel, load_robot
from planning.sphere_model import SphereModel

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class HarnessCfg:
    families: tuple[str, ...] = FAMILIES
    planners: tuple[str, ...] = ("rrtconnect",)
    problems: int = 10  # per family
    budget_s: float | None = 5.0  # None: "auto", the reference planner's mean time per family
    reference: str = "gaide"  # whose mean time "auto" hands the others
    fallback_budget_s: float = 5.0  # "auto" without the reference planner
    # test (balanced: problem i is category CATEGORIES[i % 4] of test seed i), test-legacy
    # (the family's own start and goal targets, categories as they fall), train, val
    split: str = "test"
    first: int = 0  # index of the first problem in the split
    workers: int = field(default_factory=lambda: os.cpu_count() or 1)
    mesh_check: bool = False  # also check returned paths against PyBullet's meshes
    checker: str = "compiled"  # the planners' collision checker (the harness's own check is numpy)
    problem_file: Path | None = None  # bring-your-own problems instead of the families
    robot_config: Path | None = None
    # Neural planners load WEIGHTS/<model>.pt (gaide-hybrid: gaide.pt) instead of the
    # shipped weights.
    weights: Path | None = None

    def __post_init__(self) -> None:
        if self.problems < 1 or self.workers < 1:
            raise PlanningError("need at least one problem per family and one worker")
        if self.weights is not None:
            kinds = {p.removesuffix("-hybrid") for p in self.planners if is_neural(p)}
            missing = sorted(k for k in kinds if not (self.weights / f"{k}.pt").is_file())
            if missing:
                raise PlanningError(
                    f"--weights {self.weights} has no {', '.join(m + '.pt' for m in missing)} "
                    "for the neural planners asked for"
                )
        if self.budget_s is not None and self.budget_s <= 0:
            raise PlanningError(f"budget must be > 0 s, got {self.budget_s}")
        valid = planner_names()
        bad = [p for p in self.planners if p not in valid]
        if bad:
            raise PlanningError(f"unknown planners {bad}; valid: {valid}")


@dataclass(frozen=True)
class RunRecord:
    family: str
    problem: str
    seed: int
    difficulty: str
    planner: str
    status: str  # PlanStatus value, or "bad_path" when the harness's check refused the path
    success: bool  # the planner said SUCCESS and the harness's check passed
    time_s: float
    cost: float | None  # joint-space length (rad) of a checked path
    budget_s: float
    detail: str = ""
    overhead_s: float = 0.0  # problem generation + path check (harness time, not planner time)
    # neural planners: proposal steps, those where no dropout rollout was valid, those
    # where no proposal was valid, the widened second draw included, and those where valid
    # proposals were drawn but no valid edge joined any to the tree
    proposal_steps: int = 0
    no_valid_proposals: int = 0
    no_valid_rollouts: int = 0
    no_reachable_proposals: int = 0


# -- worker side -------------------------------------------------------------------------

_ROBOT: tuple[RobotModel, SphereModel] | None = None
_WEIGHTS: Path | None = None  # see HarnessCfg.weights


def _init_worker(robot_config: str | None, weights: str | None = None) -> None:
    global _ROBOT, _WEIGHTS
    _WEIGHTS = None if weights is None else Path(weights)
    import torch

    from planning.sphere_model import SphereModel

    # One worker per core: a worker's own torch threads would only fight the others'.
    torch.set_num_threads(1)

    robot = load_robot(robot_config)
    assert robot.config.spheres is not None
    _ROBOT = (robot, SphereModel.load_for(robot.config.spheres, robot))
    try:
        from ompl import util as ou

        ou.setLogLevel(ou.LogLevel.LOG_NONE)
    except ImportError:  # pragma: no cover - ompl is a dependency
        pass


@lru_cache(maxsize=64)
def _problem(key: tuple[str, int, str | None]) -> Problem:
    assert _ROBOT is not None
    return generate_problem(key[0], key[1], *_ROBOT, category=key[2])


def _run(
    task: tuple[dict[str, Any] | tuple[str, int, str | None], str, float, bool, str],
) -> RunRecord:
    spec, planner_name, budget, mesh_check, backend = task
    assert _ROBOT is not None
    robot, spheres = _ROBOT
    t0 = time.perf_counter()
    problem = (
        _problem(spec) if isinstance(spec, tuple) else problem_from_dict(spec, "problem", robot.dof)
    )
    gen_s = time.perf_counter() - t0
    from planning.checker import make_checker

    checker = make_checker(robot, spheres, problem.world, backend=backend)
    rng = np.random.default_rng([problem.seed, zlib.crc32(planner_name.encode())])
    checkpoint = None
    if _WEIGHTS is not None and is_neural(planner_name):
        checkpoint = _WEIGHTS / f"{planner_name.removesuffix('-hybrid')}.pt"
    planner = make_planner(planner_name, checkpoint=checkpoint)
    result = _plan(planner, checker, problem, budget, rng)
    t1 = time.perf_counter()
    status, success, cost, detail = result.status.value, False, None, result.detail
    if result.status is PlanStatus.SUCCESS:
        check = check_path(
            result.path,
            problem.start,
            problem.goals,
            robot,
            spheres,
            problem.world,
            meshes=mesh_check,
        )
        if check.ok:
            success, cost = True, result.cost
        else:
            status, detail = "bad_path", check.detail
    return RunRecord(
        family=problem.family,
        problem=problem.name,
        seed=problem.seed,
        difficulty=problem.difficulty,
        planner=planner_name,
        status=status,
        success=success,
        time_s=result.time_s,
        cost=cost,
        budget_s=budget,
        detail=detail,
        overhead_s=gen_s + time.perf_counter() - t1,
        proposal_steps=int(result.stats.get("proposal_steps", 0)),
        no_valid_proposals=int(result.stats.get("no_valid_proposals", 0)),
        no_valid_rollouts=int(result.stats.get("no_valid_rollouts", 0)),
        no_reachable_proposals=int(result.stats.get("no_reachable_proposals", 0)),
    )


@runtime_checkable
class _ManyGoals(Protocol):
    """A planner rooted at several starts and goals at once (rrtc, the OMPL planners)."""

    def plan_between(
        self,
        checker: CollisionChecker,
        starts: npt.NDArray[np.float64],  # (m, dof) rad
        goals: npt.NDArray[np.float64],  # (n, dof) rad
        *,
        budget_s: float,
        rng: np.random.Generator,
    ) -> PlanResult: ...


def _plan(
    planner: Planner,
    checker: CollisionChecker,
    problem: Problem,
    budget_s: float,
    rng: np.random.Generator,
) -> PlanResult:
    """``planner`` on ``problem``: to its goal, or to any of its several goals."""
    if len(problem.goals) == 1:
        return planner.plan(checker, problem.start, problem.goal, budget_s=budget_s, rng=rng)
    t0 = time.perf_counter()
    # plan_between wants valid ends: the statuses plan() gives, for the start and for the
    # goals when none of them is valid; invalid goals among valid ones are left out.
    valid = checker.config_valid(problem.goals)
    bad = check_endpoints(checker, problem.start, problem.goals[int(np.argmax(valid))])
    if bad is not None:
        status, detail = bad
        if status is PlanStatus.GOAL_INVALID:
            why = detail.removeprefix("goal: ")
            detail = f"all {len(problem.goals)} goals are invalid; goal 0: {why}"
        return PlanResult(planner.name, status, None, time.perf_counter() - t0, detail=detail)
    goals = problem.goals[valid]
    spent = time.perf_counter() - t0
    left = max(budget_s - spent, 1e-3)
    if isinstance(planner, _ManyGoals):
        result = planner.plan_between(checker, problem.start[None], goals, budget_s=left, rng=rng)
    else:
        # Planners without plan_between (the neural ones) take one goal: the valid goal
        # nearest the start in joint space (Euclidean, rad); the others are not tried.
        nearest = goals[int(np.argmin(np.linalg.norm(goals - problem.start, axis=1)))]
        result = planner.plan(checker, problem.start, nearest, budget_s=left, rng=rng)
    return replace(result, time_s=result.time_s + spent)


# -- driver ------------------------------------------------------------------------------


def _share(part: int, whole: int) -> float | None:
    return part / whole if whole else None


def _success_by_category(runs: list[RunRecord]) -> dict[str, dict[str, float]]:
    """{category: {"success_rate", "n"}} over ``runs`` (problem files: their difficulty)."""
    out: dict[str, dict[str, float]] = {}
    for cat in dict.fromkeys(r.difficulty for r in runs):
        mine = [r.success for r in runs if r.difficulty == cat]
        out[cat or "unknown"] = {"success_rate": float(np.mean(mine)), "n": len(mine)}
    return out


_BAD_PROBLEM = (PlanStatus.START_INVALID.value, PlanStatus.GOAL_INVALID.value)


def _posed(runs: list[RunRecord]) -> list[RunRecord]:
    """The runs of well-posed problems (a start or goal in collision is the problem's fault,
    not the planner's: not counted)."""
    return [r for r in runs if r.status not in _BAD_PROBLEM]


#: A path is the shorter of two only when it is shorter by more than this share of the
#: other's cost (smaller differences are the shortcut pass's rounding, not another route).
COST_TIE = 1e-3


def _paired(a: list[RunRecord], b: list[RunRecord]) -> dict[str, Any]:
    """Two planners' runs of one family, paired by problem: the problems only one of them
    solved, and among those both solved, the problems where one's path is the shorter. Each
    split comes with its exact two-sided sign-test p-value (for success, McNemar's exact
    test): how likely a split at least as uneven is if the two were alike."""
    from scipy.stats import binomtest

    def p_value(x: int, y: int) -> float:
        return float(binomtest(x, x + y).pvalue) if x + y else 1.0

    runs_b = {r.problem: r for r in b}
    pairs = [(r, runs_b[r.problem]) for r in a if r.problem in runs_b]
    a_only = sum(ra.success and not rb.success for ra, rb in pairs)
    b_only = sum(rb.success and not ra.success for ra, rb in pairs)
    both = [
        (ra.cost, rb.cost)
        for ra, rb in pairs
        if ra.success and rb.success and ra.cost is not None and rb.cost is not None
    ]
    a_shorter = sum(ca < cb * (1 - COST_TIE) for ca, cb in both)
    b_shorter = sum(cb < ca * (1 - COST_TIE) for ca, cb in both)
    return {
        "problems": len(pairs),
        "a_only": a_only,
        "b_only": b_only,
        "success_p": p_value(a_only, b_only),
        "both": len(both),
        "a_shorter": a_shorter,
        "b_shorter": b_shorter,
        "cost_p": p_value(a_shorter, b_shorter),
    }


@dataclass
class HarnessResult:
    cfg: HarnessCfg
    records: list[RunRecord]
    budgets: dict[str, dict[str, float]]  # family -> planner -> budget (s)
    wall_s: float
    notes: list[str]

    def summary(self) -> dict[str, dict[str, dict[str, Any]]]:
        """{family: {planner: figures}} in the harness's JSON layout."""
        out: dict[str, dict[str, dict[str, Any]]] = {}
        for rec in self.records:
            out.setdefault(rec.family, {}).setdefault(rec.planner, {})
        for fam, per in out.items():
            for planner in per:
                runs = [r for r in self.records if r.family == fam and r.planner == planner]
                counted = _posed(runs)
                bad = [r for r in runs if r.status in _BAD_PROBLEM]
                times = np.array([r.time_s for r in counted]) if counted else np.zeros(0)
                costs = np.array([r.cost for r in counted if r.success and r.cost is not None])
                per[planner] = {
                    "n": len(counted),
                    "bad_problems": len(bad),
                    "success_rate": float(np.mean([r.success for r in counted]))
                    if counted
                    else 0.0,
                    "time_mean_s": float(times.mean()) if len(times) else None,
                    "time_std_s": float(times.std()) if len(times) else None,
                    "time_median_s": float(np.median(times)) if len(times) else None,
                    "cost_median": float(np.median(costs)) if len(costs) else None,
                    "cost_mean": float(costs.mean()) if len(costs) else None,
                    "budget_s": self.budgets.get(fam, {}).get(planner),
                    "bad_paths": sum(r.status == "bad_path" for r in runs),
                    "success_by_category": _success_by_category(counted),
                    "no_valid_proposal_share": _share(
                        sum(r.no_valid_proposals for r in counted),
                        sum(r.proposal_steps for r in counted),
                    ),
                    # The same share before the widened draw: dropout rollouts alone.
                    "no_valid_rollout_share": _share(
                        sum(r.no_valid_rollouts for r in counted),
                        sum(r.proposal_steps for r in counted),
                    ),
                    # Valid proposals, but none joined to the tree by a valid edge (the
                    # planner then draws a widened set for one that is).
                    "no_reachable_proposal_share": _share(
                        sum(r.no_reachable_proposals for r in counted),
                        sum(r.proposal_steps for r in counted),
                    ),
                }
        return out

    def by_category(self) -> dict[str, dict[str, Any]]:
        """{planner: {category: success rate over every family, and the count}}."""
        out: dict[str, dict[str, Any]] = {}
        for planner in dict.fromkeys(r.planner for r in self.records):
            runs = [r for r in _posed(self.records) if r.planner == planner]
            out[planner] = _success_by_category(runs)
        return out

    def paired(self) -> dict[str, dict[str, dict[str, Any]]]:
        """{family: {"A vs B": figures}} for every two planners, in the order asked for, on
        the problems both ran (see :func:`_paired`; "a" is A, "b" is B). Success rates of
        50 problems differ by a few problems between planners that are alike, so this says
        whether a difference in a table is more than the sample's."""
        counted = _posed(self.records)
        ran = {r.planner for r in counted}
        planners = [p for p in self.cfg.planners if p in ran]
        out: dict[str, dict[str, dict[str, Any]]] = {}
        for fam in dict.fromkeys(r.family for r in counted):
            runs = {p: [r for r in counted if r.family == fam and r.planner == p] for p in planners}
            out[fam] = {
                f"{a} vs {b}": _paired(runs[a], runs[b])
                for i, a in enumerate(planners)
                for b in planners[i + 1 :]
                if runs[a] and runs[b]
            }
        return out

    def figures(self) -> dict[str, Any]:
        planner_s = sum(r.time_s for r in self.records)
        overhead_s = sum(r.overhead_s for r in self.records)
        busy = planner_s + overhead_s
        return {
            "wall_s": self.wall_s,
            "planner_s": planner_s,
            "harness_overhead_s": overhead_s,
            "overhead_share": overhead_s / planner_s if planner_s else None,
            "core_utilisation": busy / (self.wall_s * self.cfg.workers) if self.wall_s else None,
            "runs": len(self.records),
        }

    def to_json(self) -> dict[str, Any]:
        return {
            "results": self.summary(),
            "by_category": self.by_category(),
            "paired": self.paired(),
            "figures": self.figures(),
            "budgets": self.budgets,
            "notes": self.notes,
            "config": {
                k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(self.cfg).items()
            },
            "runs": [asdict(r) for r in self.records],
        }


def _specs(
    cfg: HarnessCfg, dof: int
) -> list[tuple[str, dict[str, Any] | tuple[str, int, str | None]]]:
    """(family, problem spec) for every problem of the benchmark."""
    if cfg.problem_file is not None:
        return [(p.family, p.to_dict()) for p in load_problems(cfg.problem_file, dof)]
    return [
        (fam, split_problem(fam, cfg.split, cfg.first + i))
        for fam in cfg.families
        for i in range(cfg.problems)
    ]


SPLITS = ("test", "test-legacy", "train", "val")


def split_problem(family: str, split: str, i: int) -> tuple[str, int, str | None]:
    """(family, seed, category) of problem ``i`` of ``split``: the test split is balanced
    over the four categories (25% each, in turn); ``test-legacy`` is the test seeds with
    the family's own targets, as the tables before it were measured; train and val take
    the family's own targets too."""
    if split not in SPLITS:
        raise PlanningError(f"unknown split '{split}'; valid: {list(SPLITS)}")
    if split == "test":
        return family, split_seed("test", i), CATEGORIES[i % len(CATEGORIES)]
    return family, split_seed(split.removesuffix("-legacy"), i), None


def run_harness(
    cfg: HarnessCfg, progress: Callable[..., Iterable[Any]] | None = None
) -> HarnessResult:
    robot = load_robot(cfg.robot_config)
    specs = _specs(cfg, robot.dof)
    families = list(dict.fromkeys(f for f, _ in specs))
    notes: list[str] = []
    budgets: dict[str, dict[str, float]] = {f: {} for f in families}
    records: list[RunRecord] = []
    t0 = time.perf_counter()
    # Load the compiled kernels before the workers fork, so that no timed run pays the first
    # call's load from numba's cache (~0.3 s in all; measured: a first rrtc run 28.8 ms
    # instead of 1.8, a first rrtconnect run, whose validity callback is compiled, 9.9 ms
    # instead of 1.0).
    from planning.compiled.warmup import warm_up

    warm_up()
    ctx = mp.get_context("fork")
    config = None if cfg.robot_config is None else str(cfg.robot_config)
    weights = None if cfg.weights is None else str(cfg.weights)
    with ctx.Pool(cfg.workers, initializer=_init_worker, initargs=(config, weights)) as pool:

        def run_all(tasks: list[tuple[Any, str, float, bool, str]]) -> None:
            # longest first keeps both cores busy to the end
            tasks.sort(key=lambda t: -t[2])
            it = pool.imap_unordered(_run, tasks)
            for rec in progress(it, total=len(tasks), desc="planning") if progress else it:
                records.append(rec)

        others = list(cfg.planners)
        if cfg.budget_s is None and cfg.reference in cfg.planners:
            ref_budget = cfg.fallback_budget_s
            run_all(
                [
                    (spec, cfg.reference, ref_budget, cfg.mesh_check, cfg.checker)
                    for _, spec in specs
                ]
            )
            for fam in families:
                times = [
                    r.time_s for r in records if r.family == fam and r.planner == cfg.reference
                ]
                budgets[fam][cfg.reference] = ref_budget
                mean = float(np.mean(times)) if times else ref_budget
                for p in cfg.planners:
                    if p != cfg.reference:
                        # As the paper: the classical planners get the reference's mean time;
                        # the other neural planners run under the same budget as the reference.
                        budgets[fam][p] = ref_budget if is_neural(p) else max(mean, 0.05)
            others = [p for p in cfg.planners if p != cfg.reference]
            notes.append(
                f"budget auto: the classical planners get each family's mean {cfg.reference} "
                f"time; neural planners {ref_budget} s"
            )
        else:
            fixed = cfg.budget_s if cfg.budget_s is not None else cfg.fallback_budget_s
            if cfg.budget_s is None:
                notes.append(
                    f"budget auto without '{cfg.reference}' in the planners: fixed {fixed} s"
                )
            for fam in families:
                for p in cfg.planners:
                    budgets[fam][p] = fixed
        run_all(
            [
                (spec, p, budgets[fam][p], cfg.mesh_check, cfg.checker)
                for fam, spec in specs
                for p in others
            ]
        )
    return HarnessResult(cfg, records, budgets, time.perf_counter() - t0, notes)
