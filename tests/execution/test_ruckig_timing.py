from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from execution.ruckig_timing import RuckigParameterizer
from execution.timing_cfg import TimingCfg, TimingMode, timing_phrase
from execution.trajectory import TimingStatus
from execution.verify import distance_to_path, limit_violations, path_deviation, swept_collisions
from gaide_core.errors import TimingError
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.primitives import PrimitiveWorld, Sphere
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel

DOF = 6


@st.composite
def paths_and_limits(draw: st.DrawFn) -> tuple[np.ndarray, TimingCfg]:
    """2-5 waypoints within 0.7 rad of the home configuration, and per-joint limits (with
    random scale factors) far from the UR5's."""
    k = draw(st.integers(2, 5))
    offsets = draw(
        st.lists(st.lists(st.floats(-0.7, 0.7), min_size=DOF, max_size=DOF), min_size=k, max_size=k)
    )
    vec = st.lists(st.floats(0.3, 3.0), min_size=DOF, max_size=DOF)
    cfg = TimingCfg(
        mode=draw(st.sampled_from(list(TimingMode))),
        rate_hz=draw(st.sampled_from([125.0, 500.0, 1000.0])),
        max_velocity=tuple(draw(vec)),
        max_acceleration=tuple(4.0 * v for v in draw(vec)),
        max_jerk=tuple(30.0 * v for v in draw(vec)),
        velocity_scale=draw(st.floats(0.3, 1.0)),
        jerk_scale=draw(st.floats(0.3, 1.0)),
        # In free space shortcutting leaves one edge: without it the corners are timed too.
        shortcut=draw(st.booleans()),
    )
    return np.asarray(offsets), cfg


@settings(
    max_examples=30,
    deadline=None,
    suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow],
)
@given(paths_and_limits())
def test_limits_hold_at_every_sample(
    free_checker: CollisionChecker, robot: RobotModel, case: tuple[np.ndarray, TimingCfg]
) -> None:
    offsets, cfg = case
    path = robot.named_configuration("home") + offsets
    assume(np.all(np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-3))
    assume(bool(free_checker.edges_valid(path[:-1], path[1:]).all()))
    traj = RuckigParameterizer(cfg).parameterize(path, free_checker)
    lim = traj.limits
    assert lim is not None
    # The requested limits, scaled, are the ones kept.
    np.testing.assert_allclose(lim.velocity, np.asarray(cfg.max_velocity) * cfg.velocity_scale)
    assert limit_violations(traj, rate_hz=1000.0, tol=1e-6) == 0
    # The controller-rate samples themselves, jerk included.
    assert np.all(np.abs(traj.qd) <= lim.velocity + 1e-6)
    assert np.all(np.abs(traj.qdd) <= lim.acceleration + 1e-6)
    assert traj.jerk is not None and np.all(np.abs(traj.jerk) <= lim.jerk + 1e-6)
    # Uniform samples from rest at the start to rest at the goal.
    np.testing.assert_allclose(np.diff(traj.t), 1.0 / cfg.rate_hz, atol=1e-9)
    np.testing.assert_allclose(traj.q[0], path[0], atol=1e-9)
    np.testing.assert_allclose(traj.q[-1], path[-1], atol=1e-9)
    assert np.abs(traj.qd[[0, -1]]).max() < 1e-9
    if cfg.mode is TimingMode.EXACT:
        assert path_deviation(traj) <= 1e-9


def test_exact_mode_stays_on_the_path_with_unequal_limits(
    free_checker: CollisionChecker, robot: RobotModel
) -> None:
    # Joint 1 moves slightly less than joint 5 but has the lower velocity limit: Ruckig's
    # plain phase synchronization gives up here and curves (0.1 rad off on a real path).
    home = robot.named_configuration("home")
    path = np.array([home, home + np.array([1.0, 1.878, -1.057, 0.352, 0.239, 1.906])])
    cfg = TimingCfg(mode=TimingMode.EXACT, max_velocity=(3.15, 3.15, 3.15, 3.2, 3.2, 3.2))
    traj = RuckigParameterizer(cfg).parameterize(path, free_checker)
    assert path_deviation(traj) <= 1e-9
    assert limit_violations(traj) == 0


def test_exact_mode_stops_at_every_waypoint(
    free_checker: CollisionChecker, corner_path: np.ndarray
) -> None:
    cfg = TimingCfg(mode=TimingMode.EXACT, shortcut=False)
    traj = RuckigParameterizer(cfg).parameterize(corner_path, free_checker)
    assert traj.chain is not None
    for start in traj.chain.starts:
        _, qd, _, _ = traj.chain.evaluate(np.array([start]))
        assert np.abs(qd).max() < 1e-9
    assert path_deviation(traj) <= 1e-9
    assert [s.kind for s in traj.segments] == ["straight"] * 3


def test_blended_is_faster_than_exact_and_does_not_stop(
    free_checker: CollisionChecker, corner_path: np.ndarray
) -> None:
    exact = RuckigParameterizer(TimingCfg(mode=TimingMode.EXACT, shortcut=False))
    blended = RuckigParameterizer(TimingCfg(mode=TimingMode.BLENDED, shortcut=False))
    te = exact.parameterize(corner_path, free_checker)
    tb = blended.parameterize(corner_path, free_checker)
    assert tb.duration < 0.85 * te.duration
    assert tb.chain is not None and len(tb.chain.starts) >= 3
    _, qd, _, _ = tb.chain.evaluate(tb.chain.starts[1:])  # at the inner waypoints
    assert np.linalg.norm(qd, axis=1).min() > 0.1  # it does not stop there
    assert all(s.kind == "blend" for s in tb.segments)
    assert tb.figures["recheck_samples"] >= len(tb.t) // 2  # blends were re-checked
    assert limit_violations(tb) == 0


def test_a_blend_that_clips_an_obstacle_falls_back_and_stays_clear(
    robot: RobotModel, spheres: SphereModel, free_checker: CollisionChecker
) -> None:
    home = robot.named_configuration("home")
    path = np.array(
        [
            home,
            home + np.array([1.2, 0.0, 0.0, 0.0, 0.0, 0.0]),
            home + np.array([1.2, 0.0, -1.2, 0, 0, 0]),
        ]
    )
    cfg = TimingCfg(mode=TimingMode.BLENDED, shortcut=False)
    free = RuckigParameterizer(cfg).parameterize(path, free_checker)
    # A small ball where one of the robot's spheres passes when the free blend leaves the
    # path the most, and which the path itself clears.
    q, *_ = free.chain.evaluate(free.t)  # type: ignore[union-attr]
    worst = q[np.argmax(distance_to_path(q, path))]
    checker = None
    for c in free_checker.sphere_centers(worst[None])[0]:
        candidate = make_checker(robot, spheres, PrimitiveWorld([Sphere(0.02, c)]))
        if candidate.edges_valid(path[:-1], path[1:]).all():
            checker = candidate
            break
    assert checker is not None, "no obstacle spot that the path clears"
    assert swept_collisions(free, checker) > 0  # the full-speed blend would clip it
    traj = RuckigParameterizer(cfg).parameterize(path, checker)
    assert swept_collisions(traj, checker) == 0
    assert traj.figures["recheck_samples"] > free.figures["recheck_samples"]
    assert traj.duration > free.duration
    # what the summary says of it agrees with the status
    fallbacks = int(traj.figures["fallbacks"])
    assert (traj.status is TimingStatus.FELL_BACK) == (fallbacks > 0) == (len(traj.notes) > 0)
    said = timing_phrase("blended", fallbacks)
    assert ("where a blend collided" in said) == (fallbacks > 0)


def test_the_summary_says_how_the_waypoints_are_passed() -> None:
    assert timing_phrase("exact", 0) == "stops at every waypoint"
    assert timing_phrase("blended", 0) == "blended through every waypoint"
    assert timing_phrase("blended", 1) == (
        "blended; 1 segment stops at both ends, where a blend collided"
    )
    assert timing_phrase("blended", 3).startswith("blended; 3 segments stop at both ends")


# -- bad input -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "message"),
    [
        (np.zeros((0, 6)), "empty"),
        (np.zeros((1, 6)), "one waypoint"),
        (np.zeros((3, 5)), "expected (K, 6)"),
        ([[0.0] * 6, [0.0, 0.0, float("nan"), 0.0, 0.0, 0.0]], "waypoint 1: joint elbow_joint"),
        ([[0.0] * 6, [0.0] * 6], "no motion"),
    ],
)
def test_bad_paths_are_refused(free_checker: CollisionChecker, path: object, message: str) -> None:
    with pytest.raises(TimingError, match=message.replace("(", r"\(").replace(")", r"\)")):
        RuckigParameterizer().parameterize(path, free_checker)  # type: ignore[arg-type]


def test_a_waypoint_outside_the_limits_is_named_with_its_range(
    free_checker: CollisionChecker, robot: RobotModel
) -> None:
    path = np.stack([robot.named_configuration("home")] * 2)
    path[1, 3] = 3.5
    with pytest.raises(TimingError) as err:
        RuckigParameterizer().parameterize(path, free_checker)
    msg = str(err.value)
    assert "waypoint 1" in msg and "wrist_1_joint = 3.500000" in msg
    assert "[-3.141593, 3.141593]" in msg


def test_a_colliding_edge_is_named_with_its_links(
    robot: RobotModel, spheres: SphereModel, free_checker: CollisionChecker
) -> None:
    # Edge 1 swings the shoulder from -1.2 to +1.2 rad through home, where a ball waits at
    # the hand; the other edges stay far from it.
    home = robot.named_configuration("home")
    pan = np.array([[-1.2, 0.3, 0, 0, 0, 0], [-1.2, 0, 0, 0, 0, 0], [1.2, 0, 0, 0, 0, 0]])
    path = home + np.vstack([pan, [1.2, 0.3, 0, 0, 0, 0]])
    hand = free_checker.sphere_centers(home[None])[0][-1]
    checker = make_checker(robot, spheres, PrimitiveWorld([Sphere(0.03, hand)]))
    assert checker.edges_valid(path[:-1], path[1:]).tolist() == [True, False, True]
    with pytest.raises(TimingError) as err:
        RuckigParameterizer().parameterize(path, checker)
    msg = str(err.value)
    assert "edge 1 (waypoint 1 -> 2) collides" in msg
    assert "links in collision with the world" in msg and "wrist_3_link" in msg


@pytest.mark.parametrize(
    "changes",
    [
        {"max_velocity": (1.0, 1.0, 0.0, 1.0, 1.0, 1.0)},
        {"max_jerk": (-1.0,) * 6},
        {"velocity_scale": 0.0},
        {"acceleration_scale": 1.5},
        {"rate_hz": 0.0},
    ],
)
def test_bad_limits_are_refused(changes: dict[str, object]) -> None:
    with pytest.raises(TimingError):
        TimingCfg(**changes)  # type: ignore[arg-type]


def test_limits_of_the_wrong_length_are_refused(
    free_checker: CollisionChecker, corner_path: np.ndarray
) -> None:
    with pytest.raises(TimingError, match="expected 6, one per joint"):
        RuckigParameterizer(TimingCfg(max_velocity=(1.0, 2.0))).parameterize(
            corner_path, free_checker
        )


def test_the_last_sample_is_the_goal_exactly(
    free_checker: CollisionChecker, robot: RobotModel
) -> None:
    """A case hypothesis found: Ruckig's own end state (at_time(duration)) landed 6.5e-9 rad
    from the goal; the chain now takes each move's target as asked."""
    path = robot.named_configuration("home") + np.array(
        [[0.625, 0, 0, 0, 0.5, 0], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0.625]]
    )
    cfg = TimingCfg(
        rate_hz=125.0,
        velocity_scale=0.5,
        max_velocity=(1.0, 1.0, 1.0, 1.0, 1.0, 0.3125),
        max_acceleration=(4.0,) * 6,
        max_jerk=(30.0,) * 6,
        shortcut=False,
    )
    traj = RuckigParameterizer(cfg).parameterize(path, free_checker)
    np.testing.assert_array_equal(traj.q[-1], path[-1])
    np.testing.assert_array_equal(traj.qd[-1], np.zeros(6))
