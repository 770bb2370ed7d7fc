from __future__ import annotations

import numpy as np

from execution.corner_cut import cut_corners
from execution.string_pull import pull_string
from execution.verify import distance_to_path
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.primitives import PrimitiveWorld, Sphere
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel


def _length(p: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def test_a_detour_in_free_space_is_pulled_straight(
    free_checker: CollisionChecker, corner_path: np.ndarray
) -> None:
    out = pull_string(corner_path, free_checker)
    np.testing.assert_array_equal(out[[0, -1]], corner_path[[0, -1]])
    assert len(out) == 2  # the straight edge start -> goal is free
    assert _length(out) < _length(corner_path)


def test_pulled_and_cut_paths_keep_valid_edges_around_an_obstacle(
    robot: RobotModel, spheres: SphereModel, free_checker: CollisionChecker
) -> None:
    # A ball on the straight line start -> goal: the path must go around it.
    home = robot.named_configuration("home")
    start, goal = home + np.array([-1.2, 0, 0, 0, 0, 0]), home + np.array([1.2, 0, 0, 0, 0, 0])
    hand = free_checker.sphere_centers(home[None])[0][-1]
    checker = make_checker(robot, spheres, PrimitiveWorld([Sphere(0.05, hand)]))
    lift = np.array([0, -0.6, 0, 0, 0, 0])
    detour = np.array(
        [start, start + lift / 3, start + lift, home + lift, goal + lift, goal + lift / 3, goal]
    )
    assert checker.edges_valid(detour[:-1], detour[1:]).all()
    assert not checker.edge_valid(start, goal)
    pulled = pull_string(detour, checker)
    assert 2 < len(pulled) < len(detour)
    # A subsequence of the input's waypoints, each edge valid, shorter.
    assert all(any(np.array_equal(p, d) for d in detour) for p in pulled)
    assert checker.edges_valid(pulled[:-1], pulled[1:]).all()
    assert _length(pulled) < _length(detour)
    cut = cut_corners(pulled, checker)
    assert len(cut) > len(pulled)
    assert checker.edges_valid(cut[:-1], cut[1:]).all()
    assert _length(cut) < _length(pulled)
    # Cut points lie on the pulled path's edges.
    assert distance_to_path(cut, pulled).max() < 1e-12


def test_a_path_that_returns_keeps_its_loop(free_checker: CollisionChecker) -> None:
    a = np.zeros(6) + np.array([0, -1.5708, 1.5708, -1.5708, -1.5708, 0])
    path = np.array([a, a + 0.3, a])
    out = pull_string(path, free_checker)
    assert len(out) == 3
