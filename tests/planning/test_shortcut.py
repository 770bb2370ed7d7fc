from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaide_core.errors import PlanningError
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.ompl_planners import make_planner
from planning.planner import Array, path_length
from planning.robot_model import RobotModel
from planning.shortcut import remove_redundant, resample, shortcut
from planning.sphere_model import SphereModel
from tests.planning.ompl_problems import edges_all_valid, wall_checker, wall_problem


@pytest.fixture(scope="module")
def wall(robot: RobotModel, spheres: SphereModel) -> CollisionChecker:
    return wall_checker(robot, spheres)


def random_valid_path(checker: CollisionChecker, seed: int, waypoints: int, step: float) -> Array:
    """A random walk (K, dof) rad of ``waypoints`` valid edges of length ``step`` from the
    wall problem's start: a wandering, non-straight path."""
    rng = np.random.default_rng(seed)
    path = [wall_problem()[0]]
    while len(path) < waypoints:
        for _ in range(50):
            d = rng.normal(size=6)
            q = path[-1] + step * d / np.linalg.norm(d)
            if checker.edge_valid(path[-1], q):
                path.append(q)
                break
        else:
            raise AssertionError("the random walk is stuck")
    return np.asarray(path)


@settings(max_examples=15, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    waypoints=st.integers(2, 9),
    step=st.floats(0.05, 0.8),
)
def test_shortcut_keeps_ends_never_lengthens_and_every_edge_is_valid(
    wall: CollisionChecker, seed: int, waypoints: int, step: float
) -> None:
    path = random_valid_path(wall, seed, waypoints, step)
    out = shortcut(path, wall, np.random.default_rng(seed), iterations=96)
    np.testing.assert_array_equal(out[0], path[0])
    np.testing.assert_array_equal(out[-1], path[-1])
    assert path_length(out) <= path_length(path)
    assert len(out) <= len(path)
    assert edges_all_valid(wall, out)
    if waypoints >= 3:
        # A random walk turns at every waypoint: some corner can always be cut a little.
        assert path_length(out) < path_length(path)


def test_a_detour_in_free_space_becomes_the_straight_edge(
    robot: RobotModel, spheres: SphereModel, rng: np.random.Generator
) -> None:
    free = make_checker(robot, spheres)
    a, b = robot.named_configuration("home"), robot.named_configuration("up")
    assert free.edge_valid(a, b)
    detour = np.stack([a, a + 0.2, (a + b) / 2 + 0.3, b - 0.1, b])
    assert edges_all_valid(free, detour)
    out = shortcut(detour, free, rng)
    np.testing.assert_array_equal(out, np.stack([a, b]))


def test_shortcut_straightens_an_rrtconnect_path_around_the_wall(
    wall: CollisionChecker, rng: np.random.Generator
) -> None:
    start, goal = wall_problem()
    res = make_planner("rrtconnect").plan(wall, start, goal, budget_s=10.0, rng=rng)
    assert res.path is not None
    out = shortcut(res.path, wall, rng)
    assert path_length(out) < 0.95 * res.cost
    assert edges_all_valid(wall, out)
    assert not wall.edge_valid(start, goal)
    assert len(out) >= 3, "the wall still needs a via point"


def test_a_zero_budget_or_bad_arguments_are_refused(
    wall: CollisionChecker, rng: np.random.Generator
) -> None:
    path = np.stack(wall_problem())
    with pytest.raises(PlanningError):
        shortcut(path, wall, rng, budget_s=0.0)
    with pytest.raises(PlanningError):
        shortcut(path, wall, rng, batch=0)
    with pytest.raises(PlanningError):
        shortcut(path[0], wall, rng)  # not (K, dof)


def test_remove_redundant_drops_only_skippable_waypoints(wall: CollisionChecker) -> None:
    start, goal = wall_problem()
    res = make_planner("rrtconnect").plan(
        wall, start, goal, budget_s=10.0, rng=np.random.default_rng(2)
    )
    assert res.path is not None
    base = shortcut(res.path, wall, np.random.default_rng(2))
    assert len(base) >= 3
    # Its waypoints are all needed: none goes.
    np.testing.assert_array_equal(remove_redundant(base, wall), base)
    # The midpoint of every edge is redundant: they all go, and only they.
    mids = (base[:-1] + base[1:]) / 2
    padded = np.empty((2 * len(base) - 1, base.shape[1]))
    padded[0::2], padded[1::2] = base, mids
    np.testing.assert_array_equal(remove_redundant(padded, wall), base)


finite = st.floats(-3.0, 3.0, allow_nan=False)


@settings(max_examples=100, deadline=None)
@given(
    path=st.lists(st.lists(finite, min_size=6, max_size=6), min_size=1, max_size=8),
    max_step=st.floats(0.01, 2.0),
)
def test_resample_bounds_the_step_and_keeps_the_curve(
    path: list[list[float]], max_step: float
) -> None:
    p = np.asarray(path)
    out = resample(p, max_step)
    np.testing.assert_array_equal(out[0], p[0])
    np.testing.assert_array_equal(out[-1], p[-1])
    if len(out) > 1:
        assert np.linalg.norm(np.diff(out, axis=0), axis=1).max() <= max_step * (1 + 1e-9)
    assert path_length(out) == pytest.approx(path_length(p), rel=1e-9, abs=1e-12)
    # The input's waypoints (without repeats) appear, in order, among the output's.
    kept = [q for i, q in enumerate(p) if i == 0 or not np.array_equal(q, p[i - 1])]
    j = 0
    for q in out:
        if j < len(kept) and np.allclose(q, kept[j], atol=1e-12):
            j += 1
    assert j == len(kept)


def test_resample_step_count_is_minimal() -> None:
    path = np.array([[0.0] * 6, [1.0] + [0.0] * 5, [1.0, 0.25] + [0.0] * 4])
    out = resample(path, 0.3)
    assert len(out) == 1 + 4 + 1  # ceil(1 / 0.3) = 4 steps, then ceil(0.25 / 0.3) = 1
    with pytest.raises(PlanningError, match="max_step"):
        resample(path, 0.0)
