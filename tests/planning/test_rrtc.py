"""The compiled RRT-Connect (``rrtc``) and its shortcut pass, bounded by iterations."""

from __future__ import annotations

import numpy as np
import pytest

from gaide_core.errors import ConfigError, PlanningError
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.compiled import shortcut_kernel
from planning.families import generate_problem
from planning.family_names import FAMILIES, split_seed
from planning.path_check import check_path
from planning.planner import PlanResult, PlanStatus, path_length
from planning.registry import make_planner
from planning.robot_model import RobotModel
from planning.rrtc import CompiledRRTConnect, RRTCCfg, shorten
from planning.sphere_model import SphereModel
from tests.planning.ompl_problems import edges_all_valid, tube_checker, wall_checker, wall_problem

# Budgets in seconds are generous safety nets; what bounds a run in these tests is its
# iteration count, so they hold on a loaded machine.
BUDGET_S = 60.0


@pytest.fixture(scope="module")
def wall(robot: RobotModel, spheres: SphereModel) -> CollisionChecker:
    return wall_checker(robot, spheres)


def test_rrtc_solves_the_wall_problem_with_a_certified_shorter_path(
    wall: CollisionChecker,
) -> None:
    start, goal = wall_problem()
    res = make_planner("rrtc").plan(
        wall, start, goal, budget_s=BUDGET_S, rng=np.random.default_rng(0)
    )
    assert res.status is PlanStatus.SUCCESS, res.detail
    assert res.planner == "rrtc" and res.path is not None
    np.testing.assert_array_equal(res.path[0], start)
    np.testing.assert_array_equal(res.path[-1], goal)
    assert len(res.path) >= 3, "the straight edge is blocked"
    assert wall.first_invalid_edge(res.path) is None
    assert edges_all_valid(wall, res.path)
    assert res.cost <= res.stats["raw_cost"] + 1e-9
    assert res.stats["iterations"] >= 1 and res.stats["edge_checks"] >= 1


def test_the_same_seed_gives_the_same_path(wall: CollisionChecker) -> None:
    start, goal = wall_problem()
    planner = CompiledRRTConnect()

    def path(seed: int) -> np.ndarray:
        res = planner.plan(wall, start, goal, budget_s=BUDGET_S, rng=np.random.default_rng(seed))
        assert res.path is not None
        return res.path

    first = path(3)
    np.testing.assert_array_equal(path(3), first)
    assert any(not np.array_equal(path(s), first) for s in (4, 5, 6))


def test_an_enclosed_goal_fails_after_its_iterations(
    robot: RobotModel, spheres: SphereModel
) -> None:
    tube = tube_checker(robot, spheres)
    planner = CompiledRRTConnect(RRTCCfg(max_iterations=500))
    res = planner.plan(
        tube, np.zeros(6), robot.named_configuration("up"), budget_s=BUDGET_S,
        rng=np.random.default_rng(1),
    )  # fmt: skip
    assert res.status is PlanStatus.FAILED and res.path is None
    assert res.stats["iterations"] == 500
    assert "500 iterations" in res.detail


def test_the_clock_budget_ends_a_run_with_timeout(robot: RobotModel, spheres: SphereModel) -> None:
    tube = tube_checker(robot, spheres)
    res = CompiledRRTConnect().plan(
        tube, np.zeros(6), robot.named_configuration("up"), budget_s=0.2,
        rng=np.random.default_rng(1),
    )  # fmt: skip
    assert res.status is PlanStatus.TIMEOUT and res.path is None


def test_endpoints_in_collision_are_statuses(wall: CollisionChecker) -> None:
    start, goal = wall_problem()
    inside = goal.copy()
    inside[0] = 0.0
    res = CompiledRRTConnect().plan(wall, start, inside, budget_s=5.0, rng=np.random.default_rng(0))
    assert res.status is PlanStatus.GOAL_INVALID and "forearm_link" in res.detail


def test_plan_between_joins_one_of_many_roots(wall: CollisionChecker) -> None:
    start, goal = wall_problem()
    rng = np.random.default_rng(7)
    shift = np.eye(6)
    starts = np.stack([start, start + 0.3 * shift[3], start + 0.4 * shift[4]])
    goals = np.stack([goal + 0.5 * shift[5], goal])
    assert wall.config_valid(starts).all() and wall.config_valid(goals).all()
    res = CompiledRRTConnect().plan_between(wall, starts, goals, budget_s=BUDGET_S, rng=rng)
    assert res.path is not None, res.detail
    i, j = res.stats["start_index"], res.stats["goal_index"]
    np.testing.assert_array_equal(res.path[0], starts[i])
    np.testing.assert_array_equal(res.path[-1], goals[j])
    assert wall.first_invalid_edge(res.path) is None
    # Roots in any memory layout (here column-major, whose rows are strided) plan alike.
    again = CompiledRRTConnect().plan_between(
        wall, np.asfortranarray(starts), np.asfortranarray(goals), budget_s=BUDGET_S,
        rng=np.random.default_rng(7),
    )  # fmt: skip
    np.testing.assert_array_equal(again.path, res.path)
    with pytest.raises(PlanningError, match="starts must be a finite"):
        CompiledRRTConnect().plan_between(wall, starts[:, :5], goals, budget_s=1.0, rng=rng)


def test_trees_that_outgrow_their_arrays_plan_the_same_path(wall: CollisionChecker) -> None:
    """From 4 nodes a tree the arrays (and the buffer the path is traced into) double as
    the trees grow; the path is the one planned with room from the start."""
    start, goal = wall_problem()

    def plan(capacity: int) -> PlanResult:  # bounded by iterations alone (no clock)
        cfg = RRTCCfg(step=0.3, capacity=capacity, max_iterations=100_000)
        return CompiledRRTConnect(cfg).search(wall, start, goal, np.random.default_rng(5))

    small, roomy = plan(4), plan(1024)
    assert small.path is not None and roomy.path is not None
    assert max(small.stats["tree_sizes"]) > 16, "the trees outgrew 4 nodes several times"
    np.testing.assert_array_equal(small.path, roomy.path)
    assert small.stats["raw_waypoints"] == roomy.stats["raw_waypoints"]


def test_a_free_straight_edge_is_the_path(wall: CollisionChecker) -> None:
    start, _ = wall_problem()
    goal = start + 0.4 * np.eye(6)[0]
    res = CompiledRRTConnect().plan(wall, start, goal, budget_s=5.0, rng=np.random.default_rng(0))
    assert res.path is not None and len(res.path) == 2 and res.stats["straight"]


def _raw_wall_path(wall: CollisionChecker) -> PlanResult:
    """An unshortened rrtc path around the wall, bounded by iterations alone (no clock)."""
    start, goal = wall_problem()
    search = CompiledRRTConnect(RRTCCfg(simplify=False, step=0.3, max_iterations=100_000))
    return search.search(wall, start, goal, np.random.default_rng(2))


def test_shorten_keeps_the_ends_never_lengthens_and_certifies_every_edge(
    wall: CollisionChecker,
) -> None:
    raw = _raw_wall_path(wall)
    assert raw.path is not None and len(raw.path) > 4
    short = shorten(wall, raw.path, np.random.default_rng(3), 300)
    np.testing.assert_array_equal(short[0], raw.path[0])
    np.testing.assert_array_equal(short[-1], raw.path[-1])
    assert path_length(short) < path_length(raw.path)
    assert len(short) < len(raw.path)
    assert wall.first_invalid_edge(short) is None


@pytest.mark.parametrize("iterations", [0, 16, 300])
def test_shorten_leaves_no_waypoint_a_certified_edge_can_skip(
    wall: CollisionChecker, iterations: int
) -> None:
    """The pass ends with a vertex reduction: no waypoint of its result can be skipped by a
    certified edge."""
    raw = _raw_wall_path(wall)
    assert raw.path is not None and len(raw.path) > 4
    short = shorten(wall, raw.path, np.random.default_rng(3), iterations)
    i, j = np.triu_indices(len(short), k=2)
    assert i.size, "the path keeps more than two waypoints"
    assert not wall.edges_valid(short[i], short[j]).any()


def test_shorten_skips_savings_below_min_saving(wall: CollisionChecker) -> None:
    """A shortcut that saves ``min_saving`` rad or less is not taken: with a bar above the
    whole path's length the pass is its vertex reduction alone; with a small one it
    shortens further, and the shortcuts it takes save more than the bar."""
    raw = _raw_wall_path(wall)
    assert raw.path is not None
    reduced = shorten(wall, raw.path, np.random.default_rng(3), 0)
    barred = shorten(wall, raw.path, np.random.default_rng(3), 300, min_saving=1e3)
    np.testing.assert_array_equal(barred, reduced)
    free = shorten(wall, raw.path, np.random.default_rng(3), 300, min_saving=1e-3)
    assert path_length(free) < path_length(reduced) - 1e-3


def _shortcut_pass(
    checker: CollisionChecker, path: np.ndarray, seed: int, iterations: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The compiled pass on ``path`` as :func:`shorten` calls it: the result, the flags of
    its edges that lie on given ones, and the kernel's report."""
    I, F, field = checker.kernel_tables().args()  # type: ignore[attr-defined]  # noqa: E741
    rows = np.empty((len(path) + iterations + 2, path.shape[1]))
    rows[: len(path)] = path
    inherited = np.zeros(len(rows), bool)
    report, lengths = np.zeros(2, np.int64), np.zeros(2)
    u = np.random.default_rng(seed).random((iterations, 2))
    k = shortcut_kernel.shorten(
        I, F, field, rows, inherited, len(path), u, checker.margin, checker.resolution, 1e-9,
        report, lengths,
    )  # fmt: skip
    assert lengths[0] == pytest.approx(path_length(path))
    assert lengths[1] == pytest.approx(path_length(rows[:k]))
    return rows[:k], inherited[: k - 1], report


def test_the_pieces_a_shortcut_keeps_are_certified_when_they_stay(wall: CollisionChecker) -> None:
    """The kernel takes a shortcut's two pieces on the certificate of the edges they lie on,
    and certifies the ones left in the path before it returns."""
    raw = _raw_wall_path(wall)
    assert raw.path is not None
    short, inherited, report = _shortcut_pass(wall, raw.path, 0, 16)
    assert inherited.any(), "these 16 shortcuts leave pieces in the path"
    assert report.tolist() == [inherited.sum(), 0]
    assert wall.edges_valid(short[:-1], short[1:]).all()
    np.testing.assert_array_equal(short, shorten(wall, raw.path, np.random.default_rng(0), 16))


def test_a_piece_that_fails_its_certificate_gives_the_input_back(
    wall: CollisionChecker,
) -> None:
    """The pass trusts the edges it is given. Given one through the wall (start to goal,
    joint 0 swept across it), a shortcut from beyond the wall keeps the piece from the start,
    which crosses it; that piece fails at the end, and the input comes back unchanged."""
    start, goal = wall_problem()
    aside = goal + 0.6 * np.eye(6)[1]
    path = np.stack([start, goal, aside])
    assert wall.config_valid(path).all()
    assert wall.edges_valid(path[:-1], path[1:]).tolist() == [False, True]
    rows, inherited, report = _shortcut_pass(wall, path, 0, 32)
    assert report[1] == 1 and report[0] >= 1
    np.testing.assert_array_equal(rows, path)
    assert not inherited.any()
    np.testing.assert_array_equal(shorten(wall, path, np.random.default_rng(0), 32), path)


@pytest.mark.parametrize("family", FAMILIES)
def test_rrtc_solves_every_family_and_the_harness_accepts_the_path(
    family: str, robot: RobotModel, spheres: SphereModel
) -> None:
    problem = generate_problem(family, split_seed("test", 1), robot, spheres)
    checker = make_checker(robot, spheres, problem.world)
    planner = CompiledRRTConnect(RRTCCfg(max_iterations=200_000))
    res = planner.plan(
        checker, problem.start, problem.goal, budget_s=BUDGET_S, rng=np.random.default_rng(1)
    )
    assert res.status is PlanStatus.SUCCESS, res.detail
    check = check_path(res.path, problem.start, problem.goal, robot, spheres, problem.world)
    assert check.ok, check.detail


def test_bad_settings_and_checkpoints_are_refused() -> None:
    with pytest.raises(PlanningError, match="step must be"):
        RRTCCfg(step=0.0)
    with pytest.raises(PlanningError, match="max_iterations >= 1"):
        RRTCCfg(max_iterations=0)
    with pytest.raises(PlanningError, match="min_saving must be"):
        RRTCCfg(min_saving=-1e-3)
    with pytest.raises(ConfigError, match="checkpoint is for the neural planners"):
        make_planner("rrtc", checkpoint="gaide.pt")


def test_kernel_tables_come_from_the_checker_protocol(
    robot: RobotModel, spheres: SphereModel, wall: CollisionChecker
) -> None:
    # The numpy reference exports the same tables: the same seed gives the same path.
    reference = make_checker(robot, spheres, wall.world, backend="numpy")
    start, goal = wall_problem()

    def path(checker: CollisionChecker) -> np.ndarray:
        res = CompiledRRTConnect().plan(
            checker, start, goal, budget_s=BUDGET_S, rng=np.random.default_rng(5)
        )
        assert res.path is not None, res.detail
        return res.path

    np.testing.assert_array_equal(path(reference), path(wall))

    class NoTables:
        """A checker that lacks the optional ``kernel_tables``."""

        def __init__(self, inner: CollisionChecker) -> None:
            self._inner = inner

        def __getattr__(self, name: str) -> object:
            if name == "kernel_tables":
                raise AttributeError(name)
            return getattr(self._inner, name)

    with pytest.raises(PlanningError, match="need a checker with kernel tables"):
        CompiledRRTConnect().plan(
            NoTables(wall),  # type: ignore[arg-type]
            start,
            goal,
            budget_s=BUDGET_S,
            rng=np.random.default_rng(5),
        )
