from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gaide_core.errors import PlanningError
from planning.collision import CollisionChecker
from planning.oracle import OracleCfg, oracle_path, oracle_quality
from planning.path_ops import resample
from planning.planner import PlanStatus, path_length
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel
from tests.planning.ompl_problems import (
    edges_all_valid,
    tube_checker,
    wall_checker,
    wall_problem,
)

# The stages before the band; the band's tests turn it on.
QUICK = OracleCfg(runs=3, iterations=5_000, shortcuts=100, rescue_iterations=0, band=0)


@pytest.fixture(scope="module")
def wall(robot: RobotModel, spheres: SphereModel) -> CollisionChecker:
    return wall_checker(robot, spheres)


def test_oracle_path_is_the_shortest_candidate_resampled(
    wall: CollisionChecker, rng: np.random.Generator
) -> None:
    start, goal = wall_problem()
    res = oracle_path(wall, start, goal, rng, QUICK)
    assert res.status is PlanStatus.SUCCESS, res.detail
    assert res.path is not None
    np.testing.assert_array_equal(res.path[0], start)
    np.testing.assert_array_equal(res.path[-1], goal)
    assert np.linalg.norm(np.diff(res.path, axis=0), axis=1).max() <= QUICK.max_step + 1e-9
    assert edges_all_valid(wall, res.path)
    costs = dict(res.stats["candidates"])
    assert set(costs) == {"rrtc#0", "rrtc#1", "rrtc#2"}
    assert res.stats["winner"] in costs
    assert res.stats["cost_before_resample"] == min(costs.values())
    assert res.cost == pytest.approx(min(costs.values()), rel=1e-9)


def test_the_same_seed_gives_the_same_label(wall: CollisionChecker) -> None:
    # Budgeted by work alone: nothing about the label depends on the clock.
    start, goal = wall_problem()
    a, b, c = (
        oracle_path(wall, start, goal, np.random.default_rng(seed), QUICK) for seed in (5, 5, 6)
    )
    assert a.path is not None and b.path is not None and c.path is not None
    np.testing.assert_array_equal(a.path, b.path)
    assert a.stats["runs"] == b.stats["runs"]
    assert c.path.shape != a.path.shape or not np.array_equal(c.path, a.path)


def test_oracle_statuses(
    wall: CollisionChecker,
    robot: RobotModel,
    spheres: SphereModel,
    rng: np.random.Generator,
) -> None:
    start, goal = wall_problem()
    inside = goal.copy()
    inside[0] = 0.0
    res = oracle_path(wall, start, inside, rng, QUICK)
    assert res.status is PlanStatus.GOAL_INVALID and "forearm_link" in res.detail
    tube = tube_checker(robot, spheres)
    cfg = OracleCfg(runs=2, iterations=300, rescue_iterations=500)
    res = oracle_path(tube, np.zeros(6), robot.named_configuration("up"), rng, cfg)
    assert res.status is PlanStatus.FAILED and res.path is None
    assert res.stats["candidates"] == []
    assert res.stats["runs"] == [
        ("rrtc#0", "failed", 300),
        ("rrtc#1", "failed", 300),
        ("rescue", "failed", 500),
    ]
    with pytest.raises(PlanningError, match="runs >= 1"):
        OracleCfg(runs=0)


def test_oracle_quality_compares_against_longer_runs(
    wall: CollisionChecker, rng: np.random.Generator
) -> None:
    start, goal = wall_problem()
    q = oracle_quality(wall, start, goal, rng, cfg=QUICK, reference_runs=2, reference_s=1.0)
    assert q["oracle_status"] == "success"
    assert [name for name, _ in q["reference_costs"]] == ["aorrtc", "bitstar"]
    assert q["reference_cost"] == min(c for _, c in q["reference_costs"])
    assert math.isfinite(q["oracle_cost"]) and math.isfinite(q["reference_cost"])
    assert q["ratio"] == pytest.approx(q["oracle_cost"] / q["reference_cost"])
    # Both beat the blocked straight edge's length, a lower bound on any path's cost.
    bound = float(np.linalg.norm(goal - start))
    assert q["oracle_cost"] > bound and q["reference_cost"] > bound
    with pytest.raises(PlanningError, match="anytime"):
        oracle_quality(wall, start, goal, rng, reference_planners=("rrtconnect",))


def test_a_tie_share_labels_the_near_shortest_path_that_heads_for_the_goal(
    wall: CollisionChecker,
) -> None:
    from planning.oracle import first_step_direction

    start, goal = wall_problem()
    toward = (goal - start) / np.linalg.norm(goal - start)
    cfg = OracleCfg(runs=4, iterations=5_000, shortcuts=100, refine=4, rescue_iterations=0, band=0)
    # The same seed gives the same candidates; only the choice among them differs.
    plain, tied = (
        oracle_path(wall, start, goal, np.random.default_rng(8), OracleCfg(**kw))
        for kw in ({**vars(cfg)}, {**vars(cfg), "tie": 1.0})
    )
    assert plain.path is not None and tied.path is not None
    assert plain.stats["candidates"] == tied.stats["candidates"]
    shortest = min(c for _, c in plain.stats["candidates"])
    assert plain.stats["cost_before_resample"] == shortest
    assert shortest <= tied.stats["cost_before_resample"] <= 2.0 * shortest
    heading = [float(first_step_direction(p.path, 0.3) @ toward) for p in (plain, tied)]
    assert heading[1] >= heading[0] - 1e-9
    assert edges_all_valid(wall, tied.path)
    with pytest.raises(PlanningError, match="tie share"):
        OracleCfg(tie=-0.1)


def _expected_raise(checker: CollisionChecker, ends: np.ndarray, extra: float) -> np.ndarray:
    """(S,) each world-checked sphere's raise: the extra clearance, at most half its own
    clearance beyond the margin at the ends (0 for the spheres the world ignores)."""
    clear = checker.sphere_clearance(ends).min(axis=0)
    raise_ = np.minimum(extra, 0.5 * (clear - checker.margin))
    return np.where(np.isfinite(clear), raise_, 0.0)


def test_an_extra_clearance_keeps_each_sphere_that_far_from_the_wall(
    wall: CollisionChecker,
) -> None:
    start, goal = wall_problem()
    ends = float(wall.world_clearance(np.stack([start, goal])).min())
    extra = 0.03
    assert ends > wall.margin + 2 * extra, "the wall problem's ends are far from the wall"
    plain, wide = (
        oracle_path(wall, start, goal, np.random.default_rng(3), replace(QUICK, clearance=c))
        for c in (0.0, extra)
    )
    assert plain.path is not None and wide.path is not None
    assert plain.stats["margin"] == wide.stats["margin"] == wall.margin
    assert plain.stats["raise_max"] == 0.0
    assert wide.stats["raise_min"] == pytest.approx(extra)
    assert wide.stats["raise_max"] == pytest.approx(extra)
    dense = resample(wide.path, 0.005)
    assert wall.world_clearance(dense).min() >= wall.margin + extra
    assert wall.world_clearance(resample(plain.path, 0.005)).min() < wall.margin + extra
    assert edges_all_valid(wall, wide.path)
    # An end where one link is near the wall: that link's spheres rise by half their own
    # clearance beyond the margin, and it does not hold down the others' raise.
    near = start.copy()
    for _ in range(200):  # swing toward the wall, 1 cm of joint 0 at a time
        if float(wall.world_clearance(near[None])[0]) <= wall.margin + 0.01:
            break
        near[0] -= 0.01
    else:
        pytest.fail("joint 0 never brought the arm within 1 cm of the margin")
    tight = oracle_path(wall, near, goal, np.random.default_rng(3), replace(QUICK, clearance=extra))
    assert tight.path is not None, tight.detail
    reach = float(wall.world_clearance(near[None])[0])
    assert tight.stats["raise_min"] == pytest.approx(0.5 * (reach - wall.margin))
    assert tight.stats["raise_max"] == pytest.approx(extra)
    expected = _expected_raise(wall, np.stack([near, goal]), extra)
    kept = wall.sphere_clearance(resample(tight.path, 0.005)) - expected
    assert kept.min() >= wall.margin, "every sphere keeps its own raise along the label"
    # The rule of the earlier data sets: every sphere as far as the tightest allows.
    old = replace(QUICK, clearance=extra, clearance_rule="tightest")
    tightest = oracle_path(wall, near, goal, np.random.default_rng(3), old)
    assert tightest.path is not None, tightest.detail
    assert tightest.stats["raise_max"] == pytest.approx(0.5 * (reach - wall.margin))
    assert tightest.stats["margin"] == pytest.approx(wall.margin + tightest.stats["raise_max"])
    with pytest.raises(PlanningError, match="extra clearance"):
        OracleCfg(clearance=0.2)
    with pytest.raises(PlanningError, match="valid: sphere, tightest"):
        OracleCfg(clearance_rule="nearest")


def test_the_band_pulls_the_label_taut(wall: CollisionChecker) -> None:
    start, goal = wall_problem()
    plain, banded = (
        oracle_path(
            wall, start, goal, np.random.default_rng(3), replace(QUICK, band=band, band_pull=False)
        )
        for band in (0, 300)
    )
    assert plain.path is not None and banded.path is not None
    # the same runs and the same winner, then the band
    assert plain.stats["candidates"] == banded.stats["candidates"]
    assert banded.stats["cost_before_band"] == plain.stats["cost_before_resample"]
    assert plain.stats["band"] is False and banded.stats["band"] is True
    assert banded.stats["cost_before_resample"] < 0.99 * plain.stats["cost_before_resample"]
    assert banded.cost == pytest.approx(banded.stats["cost_before_resample"])
    np.testing.assert_array_equal(banded.path[[0, -1]], [start, goal])
    assert edges_all_valid(wall, banded.path)
    with pytest.raises(PlanningError, match="band needs >= 0"):
        OracleCfg(band=-1)


def _corners(path: np.ndarray) -> np.ndarray:
    """The path's ends and the waypoints where its direction turns."""
    steps = np.diff(path, axis=0)
    unit = steps / np.linalg.norm(steps, axis=1, keepdims=True)
    turns = np.flatnonzero(np.einsum("ij,ij->i", unit[:-1], unit[1:]) < 1 - 1e-9) + 1
    return path[np.concatenate([[0], turns, [len(path) - 1]])]


def test_the_pulled_band_keeps_corners_on_the_band(wall: CollisionChecker) -> None:
    start, goal = wall_problem()
    banded, pulled = (
        oracle_path(wall, start, goal, rng, replace(QUICK, band=300, band_pull=pull))
        for rng, pull in ((np.random.default_rng(3), False), (np.random.default_rng(3), True))
    )
    assert banded.path is not None and pulled.path is not None
    assert pulled.stats["band"] is True
    # string pulling only skips points of the band: never longer, a few corners, and those
    # corners are points of the (resampled) band
    assert pulled.cost <= banded.cost + 1e-9
    assert edges_all_valid(wall, pulled.path)
    np.testing.assert_array_equal(pulled.path[[0, -1]], [start, goal])
    corners = _corners(pulled.path)
    assert 3 <= len(corners) < len(_corners(banded.path)) / 2
    gaps = np.linalg.norm(corners[:, None, :] - banded.path[None, :, :], axis=2).min(axis=1)
    assert gaps.max() < 0.05  # rad: each corner lies on the band (within its resampling)
    # without a band there is nothing to pull: one setting
    assert OracleCfg(band=0, band_pull=True) == OracleCfg(band=0, band_pull=False)


def test_oracle_cost_matches_its_path(wall: CollisionChecker, rng: np.random.Generator) -> None:
    start, goal = wall_problem()
    res = oracle_path(wall, start, goal, rng, OracleCfg(runs=1, iterations=5_000, max_step=0.2))
    assert res.path is not None, res.detail
    assert [src for src, _ in res.stats["candidates"]] == ["rrtc#0"]
    assert res.cost == pytest.approx(path_length(res.path))


def test_first_step_direction_and_consistency(wall: CollisionChecker) -> None:
    from planning.oracle import first_step_direction, oracle_consistency

    path = np.array([[0.0] * 6, [0.1, 0, 0, 0, 0, 0], [0.1, 0.5, 0, 0, 0, 0]])
    # 0.3 rad along: 0.1 along joint 0, then 0.2 along joint 1
    np.testing.assert_allclose(
        first_step_direction(path, 0.3), np.array([1, 2, 0, 0, 0, 0]) / 5**0.5
    )
    np.testing.assert_allclose(first_step_direction(path, 0.05), [1, 0, 0, 0, 0, 0])
    start, goal = wall_problem()
    same = oracle_consistency(wall, start, goal, (3, 3), cfg=QUICK)
    assert same["first_step_deg"] == pytest.approx(0.0, abs=1e-6) and same["cost_spread"] == 1.0
    two = oracle_consistency(wall, start, goal, (3, 4), cfg=QUICK)
    assert 0.0 <= two["first_step_deg"] <= 180.0 and two["cost_spread"] >= 1.0


def test_bench_oracle_writes_the_consistency_figures(tmp_path: Path) -> None:
    import json

    from tests.conftest import run_cli

    out = tmp_path / "oracle.json"
    res = run_cli("bench", "oracle", "--families", "tabletop", "--problems", "1", "--budget", "0.3",
                  "--runs", "3", "--refine", "3", "--tie", "0.05", "--band", "50",
                  "--no-band-pull", "--json", str(out))  # fmt: skip
    assert res.returncode == 0, res.stderr
    fig = json.loads(out.read_text())
    assert fig["oracle"]["runs"] == 3 and fig["oracle"]["tie"] == 0.05
    assert fig["oracle"]["band"] == 50 and fig["oracle"]["band_pull"] is False
    assert set(fig["first_step_disagreement_deg"]) == {"tabletop"}
    assert fig["cost_spread"]["tabletop"] >= 1.0
    assert "first steps" in res.stdout
    bad = tmp_path / "bad.json"
    res = run_cli("bench", "oracle", "--families", "tabletop", "--problems", "1", "--tie", "2",
                  "--json", str(bad))  # fmt: skip
    assert res.returncode != 0 and not bad.exists()
    assert len(res.stderr.strip().splitlines()) == 1 and "tie share" in res.stderr
