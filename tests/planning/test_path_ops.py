"""Path processing (planning.path_ops): every operation keeps certified edges certified, the
shortening ones never lengthen a path, resampling bounds the step, repair skips what the
checker rejects."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.path_ops import (
    MIN_STEP,
    BandCfg,
    cut_corners,
    first_invalid_sample,
    pull_string,
    remove_redundant,
    repair,
    resample,
    shortcut,
    tighten,
)
from planning.planner import path_length
from planning.primitives import PrimitiveWorld, Sphere
from planning.robot_model import RobotModel
from planning.rrtc import CompiledRRTConnect, RRTCCfg
from planning.sphere_model import SphereModel
from tests.planning.ompl_problems import edges_all_valid, wall_checker, wall_problem


@pytest.fixture(scope="module")
def wall(robot: RobotModel, spheres: SphereModel) -> CollisionChecker:
    return wall_checker(robot, spheres)


@pytest.fixture(scope="module")
def free(robot: RobotModel, spheres: SphereModel) -> CollisionChecker:
    """The UR5 with no obstacles (joint limits and self-collision only)."""
    return make_checker(robot, spheres)


@pytest.fixture(scope="module")
def around_wall(wall: CollisionChecker) -> Array:
    """A certified path around the wall (compiled RRT-Connect, no shortcuts, short steps)."""
    start, goal = wall_problem()
    res = CompiledRRTConnect(RRTCCfg(simplify=False, step=0.3)).plan(
        wall, start, goal, budget_s=60.0, rng=np.random.default_rng(2)
    )
    assert res.path is not None and len(res.path) > 4
    assert edges_all_valid(wall, res.path)
    return res.path


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


def is_subsequence(sub: Array, path: Array) -> bool:
    j = 0
    for q in path:
        if j < len(sub) and np.array_equal(q, sub[j]):
            j += 1
    return j == len(sub)


# -- shortcut ----------------------------------------------------------------------------------


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
    robot: RobotModel, free: CollisionChecker, rng: np.random.Generator
) -> None:
    a, b = robot.named_configuration("home"), robot.named_configuration("up")
    assert free.edge_valid(a, b)
    detour = np.stack([a, a + 0.2, (a + b) / 2 + 0.3, b - 0.1, b])
    assert edges_all_valid(free, detour)
    np.testing.assert_array_equal(shortcut(detour, free, rng), np.stack([a, b]))
    np.testing.assert_array_equal(pull_string(detour, free), np.stack([a, b]))


def test_shortcut_straightens_a_path_around_the_wall(
    wall: CollisionChecker, around_wall: Array, rng: np.random.Generator
) -> None:
    out = shortcut(around_wall, wall, rng)
    assert path_length(out) < 0.95 * path_length(around_wall)
    assert edges_all_valid(wall, out)
    start, goal = wall_problem()
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
    with pytest.raises(PlanningError, match="max_skip"):
        pull_string(path, wall, max_skip=0)


def test_remove_redundant_drops_only_skippable_waypoints(
    wall: CollisionChecker, around_wall: Array
) -> None:
    base = shortcut(around_wall, wall, np.random.default_rng(2))
    assert len(base) >= 3
    # Its waypoints are all needed: none goes.
    np.testing.assert_array_equal(remove_redundant(base, wall), base)
    # The midpoint of every edge is redundant: they all go, and only they.
    mids = (base[:-1] + base[1:]) / 2
    padded = np.empty((2 * len(base) - 1, base.shape[1]))
    padded[0::2], padded[1::2] = base, mids
    np.testing.assert_array_equal(remove_redundant(padded, wall), base)


# -- string pulling (contraction) ----------------------------------------------------------------


def farthest_reachable(path: Array, checker: CollisionChecker, max_skip: int | None) -> Array:
    """Greedy string pulling written plainly: every candidate certified, farthest first."""
    keep, i = [0], 0
    while i < len(path) - 1:
        last = len(path) - 1 if max_skip is None else min(len(path) - 1, i + max_skip)
        i = next(
            (
                j
                for j in range(last, i + 1, -1)
                if np.linalg.norm(path[j] - path[i]) > MIN_STEP
                and checker.edge_valid(path[i], path[j])
            ),
            i + 1,
        )
        keep.append(i)
    return path[keep]


@settings(max_examples=10, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    waypoints=st.integers(2, 12),
    step=st.floats(0.1, 0.8),
    max_skip=st.sampled_from([1, 3, 16, None]),
)
def test_pull_string_is_the_farthest_certified_skip_and_never_lengthens(
    wall: CollisionChecker, seed: int, waypoints: int, step: float, max_skip: int | None
) -> None:
    path = random_valid_path(wall, seed, waypoints, step)
    out = pull_string(path, wall, max_skip=max_skip)
    # The coarse pre-check only saves work: the answer is the plain greedy one.
    np.testing.assert_array_equal(out, farthest_reachable(path, wall, max_skip))
    np.testing.assert_array_equal(out[[0, -1]], path[[0, -1]])
    assert is_subsequence(out, path)
    assert edges_all_valid(wall, out)
    assert path_length(out) <= path_length(path)


def test_pulled_and_cut_paths_keep_valid_edges_around_an_obstacle(
    robot: RobotModel, spheres: SphereModel, free: CollisionChecker
) -> None:
    # A ball on the straight line start -> goal: the path must go around it.
    home = robot.named_configuration("home")
    start, goal = home + np.array([-1.2, 0, 0, 0, 0, 0]), home + np.array([1.2, 0, 0, 0, 0, 0])
    hand = free.sphere_centers(home[None])[0][-1]
    checker = make_checker(robot, spheres, PrimitiveWorld([Sphere(0.05, hand)]))
    lift = np.array([0, -0.6, 0, 0, 0, 0])
    detour = np.array(
        [start, start + lift / 3, start + lift, home + lift, goal + lift, goal + lift / 3, goal]
    )
    assert checker.edges_valid(detour[:-1], detour[1:]).all()
    assert not checker.edge_valid(start, goal)
    pulled = pull_string(detour, checker)
    assert 2 < len(pulled) < len(detour)
    assert is_subsequence(pulled, detour)
    assert checker.edges_valid(pulled[:-1], pulled[1:]).all()
    assert path_length(pulled) < path_length(detour)
    cut = cut_corners(pulled, checker)
    assert len(cut) > len(pulled)
    assert checker.edges_valid(cut[:-1], cut[1:]).all()
    assert path_length(cut) < path_length(pulled)
    # Cut points lie on the pulled path's edges.
    for q in cut:
        assert min(segment_distance(q, a, b) for a, b in itertools.pairwise(pulled)) < 1e-12


def segment_distance(q: Array, a: Array, b: Array) -> float:
    """Distance (rad) from ``q`` to the segment a -> b."""
    t = np.clip(np.dot(q - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return float(np.linalg.norm(a + t * (b - a) - q))


def test_a_path_that_returns_keeps_its_loop(robot: RobotModel, free: CollisionChecker) -> None:
    a = robot.named_configuration("home")
    path = np.array([a, a + 0.3, a])
    assert len(pull_string(path, free)) == 3
    assert len(pull_string(path, free, max_skip=None)) == 3


def test_the_tick_runs_once_per_kept_waypoint(free: CollisionChecker, robot: RobotModel) -> None:
    a = robot.named_configuration("home")
    line = a + np.linspace(0, 1, 7)[:, None] * np.array([0.5, 0.2, -0.3, 0.1, 0.4, 0.0])
    ticks: list[int] = []
    out = pull_string(line, free, max_skip=None, tick=lambda: ticks.append(1))
    np.testing.assert_array_equal(out, line[[0, -1]])
    assert len(ticks) == 1


# -- corner cutting -------------------------------------------------------------------------------


def test_cut_corners_keeps_ends_shortens_and_certifies(
    wall: CollisionChecker, around_wall: Array
) -> None:
    pulled = pull_string(around_wall, wall)
    cut = cut_corners(pulled, wall)
    np.testing.assert_array_equal(cut[[0, -1]], pulled[[0, -1]])
    assert edges_all_valid(wall, cut)
    assert path_length(cut) <= path_length(pulled)
    with pytest.raises(ValueError, match="fractions"):
        cut_corners(pulled, wall, (0.5,))


# -- resample -------------------------------------------------------------------------------------

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


def test_a_resampled_certified_path_stays_certified(
    wall: CollisionChecker, around_wall: Array
) -> None:
    dense = resample(around_wall, 0.05)
    assert np.linalg.norm(np.diff(dense, axis=0), axis=1).max() <= 0.05 * (1 + 1e-9)
    assert wall.edges_valid_sampled(dense[:-1], dense[1:]).all()


# -- repair ---------------------------------------------------------------------------------------


def test_repair_skips_an_invalid_waypoint(
    robot: RobotModel, wall: CollisionChecker, around_wall: Array
) -> None:
    start, _ = wall_problem()
    inside = start.copy()
    inside[0] = 0.0  # in the wall
    assert not wall.config_valid(inside[None])[0]
    # A waypoint in the wall, inserted right after the start, is skipped again.
    spoiled = np.insert(around_wall, 1, inside, axis=0)
    assert wall.first_invalid_edge(spoiled) == 0
    repaired, dropped, bad = repair(spoiled, wall)
    assert bad is None and dropped == 1
    np.testing.assert_array_equal(repaired, around_wall)
    # In the middle of the path: its far end is kept, the waypoint goes.
    k = len(around_wall) // 2
    outside = (around_wall[k] + around_wall[k + 1]) / 2
    outside[2] = robot.upper[2] + 0.5  # beyond the elbow's limit
    spoiled = np.insert(around_wall, k + 1, outside, axis=0)
    assert wall.first_invalid_edge(spoiled) == k
    repaired, dropped, bad = repair(spoiled, wall)
    assert bad is None and dropped == 1 and edges_all_valid(wall, repaired)
    np.testing.assert_array_equal(repaired, around_wall)


def test_repair_reports_an_edge_it_cannot_fix(wall: CollisionChecker) -> None:
    # Straight through the wall, with nothing to skip: not repairable.
    through = np.stack(wall_problem())
    out, dropped, bad = repair(through, wall)
    assert bad == 0 and dropped == 0
    np.testing.assert_array_equal(out, through)


def test_first_invalid_sample_names_where_an_edge_collides(
    wall: CollisionChecker, around_wall: Array
) -> None:
    start, goal = wall_problem()
    hit = first_invalid_sample(wall, start, goal)
    assert hit is not None
    frac, q = hit
    assert 0.0 < frac < 1.0
    np.testing.assert_allclose(q, start + frac * (goal - start))
    assert not wall.config_valid(q[None])[0]
    assert wall.diagnose(q).world_contacts
    assert first_invalid_sample(wall, around_wall[0], around_wall[1]) is None


def test_two_detours_the_same_way_round_tighten_to_one_path(wall: CollisionChecker) -> None:
    # Two RRT-Connect paths over the wall, 6.7 and 8.7 rad, shortcut to different lengths:
    # the band takes both to the taut path that way round (4.89 rad), leaving the start the
    # same way, which is what makes two oracle labels of one problem agree.
    from planning.oracle import first_step_direction

    start, goal = wall_problem()
    cfg = BandCfg(iterations=300)
    taut = []
    for seed in (0, 1):
        res = CompiledRRTConnect(RRTCCfg(simplify=False, step=0.3)).plan(
            wall, start, goal, budget_s=60.0, rng=np.random.default_rng(seed)
        )
        assert res.path is not None
        slack = shortcut(res.path, wall, np.random.default_rng(0))
        band = tighten(wall, slack, cfg)
        assert band is not None
        np.testing.assert_array_equal(band[[0, -1]], [start, goal])
        assert edges_all_valid(wall, band)
        assert path_length(band) < 0.8 * path_length(slack)
        # budgeted by iterations: the same input gives the same band
        np.testing.assert_array_equal(tighten(wall, slack, cfg), band)
        taut.append(band)
    a, b = taut
    assert path_length(a) == pytest.approx(path_length(b), rel=1e-3)
    cos = float(first_step_direction(a, 0.3) @ first_step_direction(b, 0.3))
    assert np.degrees(np.arccos(min(cos, 1.0))) < 2.0


def test_a_detour_in_free_space_tightens_to_nearly_the_straight_edge(
    robot: RobotModel, free: CollisionChecker
) -> None:
    a, b = robot.named_configuration("home"), robot.named_configuration("up")
    detour = np.stack([a, a + 0.2, (a + b) / 2 + 0.3, b - 0.1, b])
    band = tighten(free, detour)
    assert band is not None and edges_all_valid(free, band)
    assert path_length(band) == pytest.approx(float(np.linalg.norm(b - a)), rel=1e-3)
    # nothing to pull: a straight edge stays straight; one shorter than two spacings gives
    # no band
    straight = tighten(free, np.stack([a, b]))
    assert straight is not None
    assert path_length(straight) == pytest.approx(float(np.linalg.norm(b - a)), rel=1e-9)
    assert tighten(free, np.stack([a, a + 0.01])) is None


def test_a_band_that_keeps_its_clearance_may_come_out_a_little_longer(
    wall: CollisionChecker,
) -> None:
    # A path that runs on the margin over the wall: the band keeps 2 cm more, so it comes
    # out longer; it is kept within the slack and refused beyond it.
    start, goal = wall_problem()
    res = CompiledRRTConnect(RRTCCfg(simplify=False, step=0.3)).plan(
        wall, start, goal, budget_s=60.0, rng=np.random.default_rng(0)
    )
    assert res.path is not None
    tight = tighten(wall, res.path, BandCfg(iterations=300, clearance=0.001))
    assert tight is not None
    loose = tighten(wall, tight, BandCfg(iterations=300, clearance=0.05))
    assert loose is not None and edges_all_valid(wall, loose)
    grow = path_length(loose) / path_length(tight)
    assert 1.0 < grow <= 1.05
    assert tighten(wall, tight, BandCfg(iterations=300, clearance=0.05, slack=0.0)) is None


@pytest.mark.parametrize(
    "kw",
    [
        {"spacing": 0.0},
        {"clearance": -0.01},
        {"weight": float("nan")},
        {"iterations": 0},
        {"slack": -0.1},
    ],
)
def test_band_settings_outside_their_limits_are_refused(kw: dict[str, float]) -> None:
    with pytest.raises(PlanningError, match="the band needs"):
        BandCfg(**kw)  # type: ignore[arg-type]
