"""The bidirectional neural planner (Algorithm 1 with contraction, edge checks, replanning and
the hybrid fallback), driven by simple samplers so that each branch is exercised on purpose,
and by the shipped GAIDE weights on task-family problems."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from gaide_core.errors import PlanningError
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.families import generate_problem
from planning.family_names import split_seed
from planning.neural_planner import NeuralPlanner
from planning.path_check import check_path
from planning.planner import PlanStatus
from planning.primitives import PrimitiveWorld
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel


class Straight:
    """Steps of at most ``step`` rad straight toward the target, with a little noise."""

    name = "straight"

    def __init__(self, step: float = 0.3, noise: float = 0.05, seed: int = 0) -> None:
        self.step, self.noise = step, noise
        self.rng = np.random.default_rng(seed)
        self.calls = 0

    def scene(self, cloud: Any) -> Any:
        return None

    def sample(self, scene: Any, q: np.ndarray, goal: np.ndarray, n: int) -> np.ndarray:
        self.calls += 1
        d = goal - q
        d *= min(1.0, self.step / max(float(np.linalg.norm(d)), 1e-12))
        return q + d + self.noise * self.rng.standard_normal((n, len(q)))


class Stuck(Straight):
    """Proposes nothing useful: every rollout stays where it is."""

    def sample(self, scene: Any, q: np.ndarray, goal: np.ndarray, n: int) -> np.ndarray:
        self.calls += 1
        return np.repeat(q[None], n, axis=0)


@pytest.fixture(scope="module")
def box(robot: RobotModel, spheres: SphereModel) -> Any:
    return generate_problem("box", split_seed("test", 1), robot, spheres)


def _checker(robot: RobotModel, spheres: SphereModel, problem: Any) -> CollisionChecker:
    return make_checker(robot, spheres, problem.world)


def test_free_space_gives_the_straight_edge(robot: RobotModel, spheres: SphereModel) -> None:
    checker = make_checker(robot, spheres, PrimitiveWorld([]))
    start = robot.named_configuration("home")
    goal = start + np.array([0.4, -0.2, 0.1, 0.3, 0.0, 0.5])
    planner = NeuralPlanner("straight", Straight())
    res = planner.plan(
        checker, start, goal, budget_s=5.0, rng=np.random.default_rng(0), cloud=np.zeros((1, 3))
    )
    assert res.status is PlanStatus.SUCCESS
    assert np.array_equal(res.path, np.stack([start, goal]))


def test_paper_mode_fails_honestly_where_the_sampler_cannot_help(
    robot: RobotModel, spheres: SphereModel, box: Any
) -> None:
    checker = _checker(robot, spheres, box)
    assert not checker.edge_valid(box.start, box.goal), "the test needs an obstructed problem"
    stuck = Stuck()
    res = NeuralPlanner("stuck", stuck, max_steps=10).plan(
        checker, box.start, box.goal, budget_s=5.0, rng=np.random.default_rng(0)
    )
    assert res.status is PlanStatus.FAILED and res.path is None
    assert "did not meet in 10 steps" in res.detail and stuck.calls == 10


def test_hybrid_mode_bridges_what_the_sampler_cannot_with_rrt_connect(
    robot: RobotModel, spheres: SphereModel, box: Any
) -> None:
    checker = _checker(robot, spheres, box)
    res = NeuralPlanner("stuck-hybrid", Stuck(), mode="hybrid", max_steps=5).plan(
        checker, box.start, box.goal, budget_s=10.0, rng=np.random.default_rng(0)
    )
    assert res.status is PlanStatus.SUCCESS, res.detail
    assert res.stats["fallback_segments"] >= 1
    assert check_path(res.path, box.start, box.goal, robot, spheres, box.world).ok


def test_hybrid_fallback_roots_rrt_connect_at_the_neural_trees(
    robot: RobotModel, spheres: SphereModel, box: Any
) -> None:
    checker = _checker(robot, spheres, box)
    creep = Straight(step=0.02, noise=0.0)  # valid steps that cannot meet in 6 steps
    # The budget is only a ceiling (the run takes ~0.1 s): generous, for a loaded machine.
    res = NeuralPlanner("creep-hybrid", creep, mode="hybrid", rollouts=1, max_steps=6).plan(
        checker, box.start, box.goal, budget_s=120.0, rng=np.random.default_rng(0)
    )
    assert res.status is PlanStatus.SUCCESS, res.detail
    # Three steps from each end: the start and goal plus three nodes per tree are roots.
    assert res.stats["fallback_roots"] == [4, 4]
    assert check_path(res.path, box.start, box.goal, robot, spheres, box.world).ok


def test_a_straight_sampler_solves_a_box_problem_and_every_edge_passes_the_harness(
    robot: RobotModel, spheres: SphereModel, box: Any
) -> None:
    checker = _checker(robot, spheres, box)
    res = NeuralPlanner("straight", Straight(noise=0.3), mode="hybrid", rollouts=16).plan(
        checker, box.start, box.goal, budget_s=10.0, rng=np.random.default_rng(0)
    )
    assert res.status is PlanStatus.SUCCESS, res.detail
    assert check_path(res.path, box.start, box.goal, robot, spheres, box.world).ok
    assert res.stats["forward_passes"] >= 1


def test_hybrid_mode_shortens_the_contracted_path_and_paper_mode_does_not(
    robot: RobotModel, spheres: SphereModel, box: Any
) -> None:
    from planning.planner import path_length

    checker = _checker(robot, spheres, box)
    creep = Straight(step=0.02, noise=0.0)  # the fallback's bridge leaves corners to cut
    # The budget is only a ceiling (the run takes ~0.1 s): generous, for a loaded machine.
    res = NeuralPlanner("creep-hybrid", creep, mode="hybrid", rollouts=1, max_steps=6).plan(
        checker, box.start, box.goal, budget_s=120.0, rng=np.random.default_rng(0)
    )
    assert res.status is PlanStatus.SUCCESS, res.detail
    assert path_length(res.path) < res.stats["contracted_cost"]
    assert check_path(res.path, box.start, box.goal, robot, spheres, box.world).ok
    paper = NeuralPlanner("straight", Straight(noise=0.3), rollouts=16).plan(
        checker, box.start, box.goal, budget_s=10.0, rng=np.random.default_rng(0)
    )
    assert "contracted_cost" not in paper.stats
    with pytest.raises(PlanningError, match="shortcuts >= 0"):
        NeuralPlanner("x", Straight(), shortcuts=-1)


def test_contraction_drops_every_node_a_straight_edge_can_skip(
    robot: RobotModel, spheres: SphereModel
) -> None:
    from planning.neural_planner import _Run

    checker = make_checker(robot, spheres, PrimitiveWorld([]))
    planner = NeuralPlanner("straight", Straight())
    run = _Run(planner, Straight(), checker, float("inf"), np.random.default_rng(0))
    a = robot.named_configuration("home")
    path = a + np.linspace(0, 1, 7)[:, None] * np.array([0.5, 0.2, -0.3, 0.1, 0.4, 0.0])
    assert np.array_equal(run.contract(path), path[[0, -1]])


def test_bad_endpoints_are_a_status_and_bad_settings_an_error(
    robot: RobotModel, spheres: SphereModel, box: Any
) -> None:
    checker = _checker(robot, spheres, box)
    folded = np.array([0.0, 0.3, 0.0, 0.0, 0.0, 0.0])  # the arm down through the box's floor
    assert not checker.config_valid(folded[None])[0]
    planner = NeuralPlanner("straight", Straight())
    rng = np.random.default_rng(0)
    res = planner.plan(checker, folded, box.goal, budget_s=1.0, rng=rng)
    assert res.status is PlanStatus.START_INVALID and "collision" in res.detail
    res = planner.plan(checker, box.start, robot.upper + 0.1, budget_s=1.0, rng=rng)
    assert res.status is PlanStatus.GOAL_INVALID
    with pytest.raises(PlanningError, match="mode must be one of"):
        NeuralPlanner("x", Straight(), mode="fast")
    with pytest.raises(PlanningError, match="budget_s"):
        planner.plan(checker, box.start, box.goal, budget_s=0.0, rng=rng)
    with pytest.raises(PlanningError, match="restart_iterations >= 1"):
        NeuralPlanner("x", Straight(), mode="hybrid", restart_iterations=0)
    with pytest.raises(PlanningError, match=r"stall_steps >= 0; got .* -1$"):
        NeuralPlanner("x", Straight(), stall_steps=-1)


def test_the_fallback_restarts_rrt_connect_in_growing_slices(
    robot: RobotModel, spheres: SphereModel, box: Any
) -> None:
    from planning.neural_planner import _Run

    shelf = generate_problem("shelf_iii", split_seed("test", 0), robot, spheres)
    checker = _checker(robot, spheres, shelf)
    planner = NeuralPlanner("stuck-hybrid", Stuck(), mode="hybrid", restart_iterations=1)
    run = _Run(planner, Stuck(), checker, float("inf"), np.random.default_rng(0))
    # One iteration does not reach into the shelf's slot: the first slices fail, and the
    # slices grow (by iterations, not seconds) until one does.
    res = run.connect(shelf.start[None], shelf.goal[None])
    assert res is not None
    path, i, j = res
    assert (i, j) == (0, 0) and run.stats["fallback_restarts"] >= 1
    assert np.array_equal(path[0], shelf.start) and np.array_equal(path[-1], shelf.goal)
    assert checker.edges_valid(path[:-1], path[1:]).all()
    # restarts root the first start and the last goal alone, whatever the first slice had
    hand = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.1])
    starts = np.stack([shelf.start, shelf.start + hand])
    goals = np.stack([shelf.goal + hand, shelf.goal])
    assert checker.config_valid(np.concatenate([starts, goals])).all()
    res = run.connect(starts, goals)
    assert res is not None and res[1:] == (0, 1)
    assert np.array_equal(res[0][0], shelf.start) and np.array_equal(res[0][-1], shelf.goal)


def test_a_tiny_budget_times_out_saying_what_was_tried(
    robot: RobotModel, spheres: SphereModel, box: Any
) -> None:
    checker = _checker(robot, spheres, box)
    res = NeuralPlanner("stuck", Stuck(), mode="hybrid", max_steps=10_000).plan(
        checker, box.start, box.goal, budget_s=0.05, rng=np.random.default_rng(0)
    )
    assert res.status is PlanStatus.TIMEOUT and "forward passes" in res.detail


def test_the_planner_runs_torch_on_its_own_threads_and_restores_them(
    robot: RobotModel, spheres: SphereModel, box: Any
) -> None:
    import torch

    class Recording(Stuck):
        def __init__(self) -> None:
            super().__init__()
            self.seen: list[int] = []

        def sample(self, scene: Any, q: np.ndarray, goal: np.ndarray, n: int) -> np.ndarray:
            self.seen.append(torch.get_num_threads())
            return super().sample(scene, q, goal, n)

    checker = _checker(robot, spheres, box)
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        sampler = Recording()
        NeuralPlanner("rec", sampler, max_steps=2, threads=1).plan(
            checker, box.start, box.goal, budget_s=5.0, rng=np.random.default_rng(0)
        )
        assert sampler.seen == [1, 1] and torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
    with pytest.raises(PlanningError, match="threads >= 0"):
        NeuralPlanner("x", Straight(), threads=-1)


class _WallAhead:
    """A checker stub: every configuration is valid, and an edge from q is valid only where it
    turns joint 1 by more than 0.1 rad (a wall straight ahead in joint space)."""

    def __init__(self, robot: RobotModel) -> None:
        self.robot = robot

    def config_valid(self, Q: np.ndarray) -> np.ndarray:
        return np.ones(len(Q), bool)

    def edges_valid(self, Q0: np.ndarray, Q1: np.ndarray) -> np.ndarray:
        return np.abs(Q1[:, 1] - Q0[:, 1]) > 0.1


@pytest.mark.parametrize("widen_blocked", [True, False])
def test_valid_rollouts_cut_off_by_a_wall_are_widened_into_reachable_ones(
    robot: RobotModel, widen_blocked: bool
) -> None:
    from planning.neural_planner import _Run

    q = robot.named_configuration("home")
    target = q + np.array([0.6, 0.0, 0.0, 0.0, 0.0, 0.0])
    planner = NeuralPlanner("straight", Straight(noise=0.0), widen_blocked=widen_blocked)
    checker: Any = _WallAhead(robot)
    run = _Run(planner, planner.sampler_for(robot), checker, np.inf, np.random.default_rng(0))
    node = run.propose(q, target)
    assert node is not None and run.stats["no_reachable_proposals"] == 1
    assert np.linalg.norm(node - q) <= 0.3 + 1e-9  # one step at most
    # Widened: a node the tree reaches by a valid edge. Not widened: the straight rollout,
    # whose blocked edge is left to replanning.
    assert bool(abs(node[1] - q[1]) > 0.1) is widen_blocked


class _Pocket(_WallAhead):
    """A checker stub: only configurations within 0.1 rad of ``centre`` are valid (a tight
    spot), and every edge between valid ones is."""

    def __init__(self, robot: RobotModel, centre: np.ndarray) -> None:
        super().__init__(robot)
        self.centre = centre

    def config_valid(self, Q: np.ndarray) -> np.ndarray:
        return np.linalg.norm(Q - self.centre, axis=1) < 0.1

    def edges_valid(self, Q0: np.ndarray, Q1: np.ndarray) -> np.ndarray:
        return self.config_valid(Q0) & self.config_valid(Q1)


def test_in_a_tight_spot_the_widened_draw_shrinks_to_a_short_free_step(robot: RobotModel) -> None:
    from planning.neural_planner import _Run

    q = robot.named_configuration("home")
    target = q + np.array([0.6, 0.0, 0.0, 0.0, 0.0, 0.0])
    planner = NeuralPlanner("straight", Straight(noise=0.0))
    checker: Any = _Pocket(robot, q)
    run = _Run(planner, planner.sampler_for(robot), checker, np.inf, np.random.default_rng(0))
    node = run.propose(q, target)
    # Every rollout and the full widened draw leave the pocket; a quarter of it stays inside.
    assert run.stats["no_valid_rollouts"] == 1 and run.stats["no_valid_proposals"] == 0
    assert node is not None and 0 < np.linalg.norm(node - q) < 0.1


class _Away(Straight):
    """Steps 0.02 rad straight away from the target (so the gap between the trees' ends
    only grows), and records each target."""

    def __init__(self) -> None:
        super().__init__()
        self.targets: list[np.ndarray] = []

    def sample(self, scene: Any, q: np.ndarray, goal: np.ndarray, n: int) -> np.ndarray:
        self.targets.append(goal.copy())
        away = q - 0.02 * (goal - q) / np.linalg.norm(goal - q)
        return np.repeat(away[None], n, axis=0)


@pytest.mark.parametrize("stall_steps", [4, 0])
def test_trees_whose_ends_stall_aim_at_the_other_root(
    robot: RobotModel, spheres: SphereModel, box: Any, stall_steps: int
) -> None:
    checker = _checker(robot, spheres, box)
    away = _Away()
    planner = NeuralPlanner("away", away, max_steps=12, stall_steps=stall_steps)
    res = planner.plan(checker, box.start, box.goal, budget_s=60.0, rng=np.random.default_rng(0))
    assert res.status is PlanStatus.FAILED and len(away.targets) == 12
    at_root = [any(np.array_equal(t, end) for end in (box.start, box.goal)) for t in away.targets]
    # Step 0 aims at the goal, the other tree's end and root; then each step aims at the other
    # tree's moved end, until the gap has not shrunk for ``stall_steps`` steps.
    if stall_steps:
        assert at_root == [True] + [False] * 4 + [True] * 7
        assert res.stats["stalled_steps"] == 7
    else:
        assert at_root == [True] + [False] * 11
        assert res.stats["stalled_steps"] == 0
