from __future__ import annotations

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from execution.limits import JointLimits
from execution.ruckig_segments import SegmentChain, SegmentPlanner

LIMITS = JointLimits(
    names=("a", "b", "c"),
    lower=np.full(3, -5.0),
    upper=np.full(3, 5.0),
    velocity=np.array([3.0, 2.0, 1.0]),
    acceleration=np.array([8.0, 5.0, 3.0]),
    jerk=np.array([80.0, 40.0, 30.0]),
)
vec3 = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).map(np.asarray)


@settings(max_examples=30, deadline=None)
@given(vec3, vec3, vec3, vec3)
def test_state_jerk_and_extrema_agree_with_dense_sampling(
    p0: np.ndarray, p1: np.ndarray, f0: np.ndarray, f1: np.ndarray
) -> None:
    planner = SegmentPlanner(LIMITS)
    traj = planner.plan(p0, p1, f0 * LIMITS.velocity, f1 * LIMITS.velocity)
    assume(traj is not None and traj.duration > 1e-3)
    assert traj is not None
    line = planner.plan_line(p1, p0)  # from rest at p1: joins a move that ends at rest
    moves = [traj] if line is None or np.any(f1 != 0) else [traj, line]
    chain = SegmentChain(moves, 3)
    t = np.linspace(0.0, chain.duration, 6001)
    q, qd, qdd, jerk = chain.evaluate(t)
    # Velocity and acceleration are the derivatives of position and velocity (central
    # differences, h = chain.duration / 6000), jerk of acceleration away from its switches.
    h = t[1] - t[0]
    np.testing.assert_allclose((q[2:] - q[:-2]) / (2 * h), qd[1:-1], atol=50 * h * h * 80)
    np.testing.assert_allclose((qd[2:] - qd[:-2]) / (2 * h), qdd[1:-1], atol=2 * h * 80)
    smooth = np.all(np.abs(np.diff(jerk, axis=0)) < 1e-9, axis=1)
    inner = smooth[:-1] & smooth[1:]
    fd = (qdd[2:] - qdd[:-2]) / (2 * h)
    np.testing.assert_allclose(fd[inner], jerk[1:-1][inner], atol=1e-6)
    lo, hi = chain.position_extrema()
    assert np.all(q.min(axis=0) >= lo - 1e-9) and np.all(q.max(axis=0) <= hi + 1e-9)
    # Exact extrema: dense samples come within the distance covered between two samples.
    assert np.all(q.min(axis=0) - lo <= 3.0 * h + 1e-12)
    assert np.all(hi - q.max(axis=0) <= 3.0 * h + 1e-12)


def test_a_line_keeps_every_joints_own_limits_and_is_straight() -> None:
    planner = SegmentPlanner(LIMITS)
    p0, p1 = np.zeros(3), np.array([1.0, 1.02, 0.3])  # b moves most, a has the higher limits
    traj = planner.plan_line(p0, p1)
    assert traj is not None
    chain = SegmentChain([traj], 3)
    t = np.linspace(0.0, chain.duration, 2001)
    q, qd, qdd, jerk = chain.evaluate(t)
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    off = q - np.outer(q @ u, u)
    assert np.abs(off).max() < 1e-12
    assert np.all(np.abs(qd) <= LIMITS.velocity + 1e-9)
    assert np.all(np.abs(qdd) <= LIMITS.acceleration + 1e-9)
    assert np.all(np.abs(jerk) <= LIMITS.jerk + 1e-9)
    # Time-optimal along the line: some joint uses one of its limits fully.
    use = max(
        (np.abs(qd) / LIMITS.velocity).max(),
        (np.abs(qdd) / LIMITS.acceleration).max(),
        (np.abs(jerk) / LIMITS.jerk).max(),
    )
    assert use > 1 - 1e-6


def test_zero_motion_has_no_line() -> None:
    assert SegmentPlanner(LIMITS).plan_line(np.ones(3), np.ones(3)) is None


def test_vectorized_states_match_ruckigs_own() -> None:
    rng = np.random.default_rng(3)
    planner = SegmentPlanner(LIMITS)
    for _ in range(20):
        p0, p1 = rng.uniform(-1, 1, (2, 3))
        v0, v1 = rng.uniform(-0.9, 0.9, (2, 3)) * LIMITS.velocity
        traj = planner.plan(p0, p1, v0, v1)
        assert traj is not None
        t = np.linspace(0.0, traj.duration, 97)
        q, qd, qdd, _ = SegmentChain([traj], 3).evaluate(t)
        ref = [traj.at_time(x) for x in t.tolist()]
        for i, got in enumerate((q, qd, qdd)):
            np.testing.assert_allclose(got, [r[i] for r in ref], atol=1e-12)
