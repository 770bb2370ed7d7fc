from __future__ import annotations

import numpy as np
import pytest

from execution.compare import CompareCfg, compare
from execution.trajectory import TimedTrajectory
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates


def _log_of(
    traj: TimedTrajectory, delay: float, rate: float, *, lead: float = 0.5, noise: float = 1e-4
) -> JointStates:
    """What a controller running ``traj`` late by ``delay`` s logs at ``rate`` Hz, starting
    ``lead`` s before the plan's start, with position noise."""
    t = np.arange(-lead, traj.duration + 1.0, 1.0 / rate)
    q = np.stack([np.interp(t - delay, traj.t, traj.q[:, j]) for j in range(traj.dof)], axis=1)
    q += np.random.default_rng(1).normal(0.0, noise, q.shape)
    # The log names its joints in another order and has one more, and absolute stamps.
    names = (*reversed(traj.joint_names), "gripper_joint")
    q = np.hstack([q[:, ::-1], np.zeros((len(t), 1))])
    return JointStates(names=names, t=t + lead, q=q, start_ns=1_700_000_000 * 10**9)


@pytest.mark.parametrize("rate", [100.0, 250.0, 500.0])
def test_a_planted_delay_is_found_within_one_sample(
    small_traj: TimedTrajectory, rate: float
) -> None:
    log = _log_of(small_traj, 0.12, rate)
    res = compare(small_traj, log, CompareCfg(expected_start_s=0.5))
    assert res.delay_s == pytest.approx(0.12, abs=1.0 / small_traj.rate_hz)
    assert res.correlation > 0.99
    assert res.rms_rad.max() < 2e-3  # noise and interpolation only, once aligned
    assert res.overlap_s > 0.9 * small_traj.duration


@pytest.mark.parametrize("rate", [100.0, 500.0])
def test_a_delay_between_two_samples_is_found_within_a_millisecond(
    small_traj: TimedTrajectory, rate: float
) -> None:
    # 12.3 ms: between the 100 Hz plan's samples (the parabola through the correlation peak
    # places it); a servo's few-cycle delay must be told apart from the next cycle's.
    log = _log_of(small_traj, 0.0123, rate)
    res = compare(small_traj, log, CompareCfg(expected_start_s=0.5))
    assert res.delay_s == pytest.approx(0.0123, abs=1e-3)


def test_tracking_error_is_measured_after_alignment(small_traj: TimedTrajectory) -> None:
    log = _log_of(small_traj, 0.05, 500.0, noise=0.0)
    off = log.q.copy()
    off[:, 0] += 0.01  # the last joint of the trajectory (reversed order), 10 mrad off
    biased = JointStates(names=log.names, t=log.t, q=off, start_ns=log.start_ns)
    res = compare(small_traj, biased, CompareCfg(expected_start_s=0.5))
    assert res.delay_s == pytest.approx(0.05, abs=0.01)
    assert res.rms_rad[-1] == pytest.approx(0.01, abs=1e-3)
    assert res.rms_rad[:-1].max() < 2e-3


def test_a_log_without_the_plans_joints_is_refused(small_traj: TimedTrajectory) -> None:
    log = _log_of(small_traj, 0.0, 100.0)
    names = tuple(n.replace("elbow_joint", "elbow") for n in log.names)
    renamed = JointStates(names=names, t=log.t, q=log.q)
    with pytest.raises(
        ExecutionError,
        match=r"does not fit the trajectory: .*lack joints \['elbow_joint'\].*'elbow'",
    ):
        compare(small_traj, renamed)


def test_a_log_with_no_overlap_in_time_is_refused(small_traj: TimedTrajectory) -> None:
    log = _log_of(small_traj, 0.0, 100.0, lead=0.0)
    with pytest.raises(ExecutionError, match="shares no time with the plan"):
        compare(small_traj, log, CompareCfg(expected_start_s=30.0, max_delay_s=1.0))


def test_a_log_that_does_not_move_is_refused(small_traj: TimedTrajectory) -> None:
    t = np.arange(0.0, 2.0, 0.01)
    still = JointStates(names=small_traj.joint_names, t=t, q=np.tile(small_traj.q[0], (len(t), 1)))
    with pytest.raises(ExecutionError, match="no motion"):
        compare(small_traj, still)


def test_a_log_of_one_sample_is_refused(small_traj: TimedTrajectory) -> None:
    one = JointStates(names=small_traj.joint_names, t=np.zeros(1), q=small_traj.q[:1])
    with pytest.raises(ExecutionError, match=">= 2 samples"):
        compare(small_traj, one)
