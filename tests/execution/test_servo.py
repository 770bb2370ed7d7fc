"""The servo model of a real arm controller: delay, limits, noise, PD tracking, its settings."""

from __future__ import annotations

import numpy as np
import pytest

from execution.compare import compare
from execution.servo import ServoCfg, hermite_resample, servo_command
from execution.sim_cfg import SimCfg
from execution.simulate import SimResult, SimStatus, simulate
from execution.trajectory import TimedTrajectory
from gaide_core.errors import ExecutionError
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.primitives import Box, PrimitiveWorld
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel


def _run(traj: TimedTrajectory, robot: RobotModel, **servo: object) -> SimResult:
    return simulate(traj, robot, cfg=SimCfg(servo=ServoCfg(**servo)))  # type: ignore[arg-type]


@pytest.mark.parametrize("cycles", [0, 3, 8])
def test_the_servo_delays_the_motion_by_its_cycles_and_compare_recovers_them(
    small_traj: TimedTrajectory, robot: RobotModel, cycles: int
) -> None:
    res = _run(small_traj, robot, delay_cycles=cycles)
    assert res.controller == "servo" and res.rate_hz == 500.0
    assert res.delay_s == pytest.approx(cycles / 500.0)
    found = compare(small_traj, res.log)
    assert found.delay_s == pytest.approx(cycles / 500.0, abs=1e-3)  # within 1 ms
    assert found.correlation > 0.999
    # The run lasts until the delayed motion has ended: the arm is on the goal, at rest.
    assert res.log.t[-1] == pytest.approx(small_traj.duration + cycles / 500.0, abs=2.1e-3)
    np.testing.assert_allclose(res.log.q[-1], small_traj.q[-1], atol=2e-4)


def test_the_commanded_and_achieved_motion_keep_the_velocity_and_acceleration_limits(
    small_traj: TimedTrajectory, robot: RobotModel
) -> None:
    v_max, a_max = 0.5, 3.0
    assert np.abs(small_traj.qd).max() > 2 * v_max  # the plan asks for more
    assert np.abs(small_traj.qdd).max() > 2 * a_max
    res = _run(
        small_traj,
        robot,
        max_velocity=(v_max,) * 6,
        max_acceleration=(a_max,) * 6,
        encoder_noise_rad=0.0,  # the log is then the arm's true motion
    )
    assert res.limited_cycles > 0
    dt = 1.0 / res.rate_hz
    v = np.diff(res.log.q, axis=0) / dt
    a = np.diff(v, axis=0) / dt
    assert np.abs(v).max() <= v_max * (1 + 1e-3)
    assert np.abs(v).max() >= v_max * (1 - 1e-3)  # the limit is what held it back
    assert np.abs(a).max() <= a_max * (1 + 1e-2)
    # Held back, the arm still arrives: the run lasts until it has.
    assert res.log.t[-1] > small_traj.duration + 1.0
    np.testing.assert_allclose(res.log.q[-1], small_traj.q[-1], atol=1e-4)


def test_a_trajectory_within_the_limits_passes_the_limiter_unchanged(
    small_traj: TimedTrajectory, robot: RobotModel
) -> None:
    times = np.arange(0, round(small_traj.duration * 500) + 1) / 500.0
    assert small_traj.chain is not None
    targets = small_traj.chain.evaluate(times)[0]
    cmd = servo_command(targets, 1 / 500, 4, robot.velocity_limits, robot.acceleration_limits)
    assert cmd.limited_cycles == 0
    np.testing.assert_array_equal(cmd.q[:5], np.repeat(targets[:1], 5, axis=0))  # the FIFO
    np.testing.assert_allclose(cmd.q[4:], targets[:-4], atol=1e-12)


def test_hermite_resampling_matches_the_ruckig_segments(small_traj: TimedTrajectory) -> None:
    assert small_traj.chain is not None
    times = np.linspace(0.0, small_traj.duration, 3001)
    exact = small_traj.chain.evaluate(times)[0]
    t, q, qd, qdd = small_traj.t, small_traj.q, small_traj.qd, small_traj.qdd
    got = hermite_resample(t, q, qd, qdd, times)
    np.testing.assert_allclose(got, exact, atol=1e-6)  # 100 Hz samples, piecewise cubics
    np.testing.assert_allclose(hermite_resample(t, q, qd, qdd, t), q, rtol=0, atol=1e-12)


def test_encoder_noise_is_seeded(small_traj: TimedTrajectory, robot: RobotModel) -> None:
    a, b = _run(small_traj, robot, seed=7), _run(small_traj, robot, seed=7)
    np.testing.assert_array_equal(a.log.q, b.log.q)
    np.testing.assert_array_equal(a.log.qd, b.log.qd)
    other = _run(small_traj, robot, seed=8)
    assert not np.array_equal(a.log.q, other.log.q)
    # A generator passed in draws the same noise as its seed.
    given = simulate(small_traj, robot, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(given.log.q, a.log.q)


def test_tracking_error_is_nonzero_but_small_on_a_smooth_trajectory(
    small_traj: TimedTrajectory, robot: RobotModel
) -> None:
    res = simulate(small_traj, robot)  # the defaults: 3 cycles, 1e-5 rad noise
    assert res.status is SimStatus.CLEAR
    # Against the plan at the same time: mostly the 6 ms delay (2.5 rad/s at most).
    assert 1e-3 < res.rms_all_rad < 0.01
    assert 1e-3 < res.max_all_rad < 0.02
    # The delay taken out: the encoder noise and the PD loop's answer to it.
    rms_after, max_after = res.rms_after_delay_all_rad, res.max_after_delay_all_rad
    assert rms_after is not None and max_after is not None
    assert 1e-6 < rms_after < 1e-4 and max_after < 5e-4
    assert res.saturated_cycles == 0 and res.limited_cycles == 0
    noiseless = _run(small_traj, robot, encoder_noise_rad=0.0, delay_cycles=0)
    assert noiseless.max_all_rad < max_after


def test_the_clearance_along_the_executed_motion_is_reported(
    small_traj: TimedTrajectory,
    robot: RobotModel,
    spheres: SphereModel,
    free_checker: CollisionChecker,
) -> None:
    free = simulate(small_traj, robot, checker=free_checker)
    assert free.executed_min_clearance_m == np.inf and free.clearance_ok is True
    assert free.summary()["executed_min_clearance_m"] is None  # JSON has no infinity
    assert free.executed_invalid == 0
    # A wall beside the motion: the executed clearance is the plan's, to the tracking error.
    pose = np.eye(4)
    pose[:3, 3] = [0.2, -0.25, 0.3]
    world = PrimitiveWorld([Box(np.array([1.5, 0.05, 1.0]), pose)])
    checker = make_checker(robot, spheres, world)
    planned = float(checker.world_clearance(small_traj.q).min())
    assert 0.005 < planned < 0.3
    res = simulate(small_traj, robot, primitives=world, checker=checker)
    assert res.status is SimStatus.CLEAR
    assert res.executed_min_clearance_m == pytest.approx(planned, abs=2e-3)
    assert res.clearance_margin_m == checker.margin and res.clearance_ok is True
    summary = res.summary()
    assert summary["executed_min_clearance_m"] == res.executed_min_clearance_m
    assert summary["executed_clearance_ok"] is True and summary["executed_invalid_samples"] == 0


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("rate_hz", 10, r"servo\.rate_hz must be a number in \[50, 2000\] Hz, got 10"),
        ("delay_cycles", -1, r"servo\.delay_cycles must be an integer in \[0, 100\], got -1"),
        ("delay_cycles", 2.5, r"servo\.delay_cycles must be an integer"),
        ("max_velocity", (1.0, -1.0), r"servo\.max_velocity must be a list of numbers > 0"),
        ("max_acceleration", "fast", r"servo\.max_acceleration must be comma-separated"),
        ("bandwidth_hz", 30.0, r"servo\.bandwidth_hz must be a number in \(0, 25\] Hz"),
        ("damping_ratio", 0.0, r"servo\.damping_ratio must be a number in \[0.1, 2\]"),
        ("encoder_noise_rad", -1e-5, r"servo\.encoder_noise_rad must be a number in \[0, 0.01\]"),
        ("seed", -1, r"servo\.seed must be an integer in \[0, inf\]"),
    ],
)
def test_bad_servo_settings_name_the_field_and_the_valid_range(
    field: str, value: object, message: str
) -> None:
    with pytest.raises(ExecutionError, match=message):
        ServoCfg(**{field: value})  # type: ignore[arg-type]


def test_the_simulator_settings_hold_the_servo_settings() -> None:
    assert SimCfg().controller == "servo" and SimCfg().servo == ServoCfg()
    from_yaml = SimCfg(servo={"delay_cycles": 5, "max_velocity": [1, 2, 3, 1, 2, 3]})  # type: ignore[arg-type]
    assert from_yaml.servo == ServoCfg(delay_cycles=5, max_velocity=(1, 2, 3, 1, 2, 3))
    assert from_yaml.servo.delay_s == pytest.approx(0.01)
    with pytest.raises(ExecutionError, match=r"servo: unknown keys \['delay'\]; valid: \["):
        SimCfg(servo={"delay": 5})  # type: ignore[arg-type]
    with pytest.raises(ExecutionError, match=r"servo must be a mapping"):
        SimCfg(servo=3)  # type: ignore[arg-type]
    with pytest.raises(ExecutionError, match=r"controller must be one of \['servo', 'ideal'\]"):
        SimCfg(controller="pid")


def test_per_joint_limits_must_fit_the_robot(
    small_traj: TimedTrajectory, robot: RobotModel
) -> None:
    with pytest.raises(ExecutionError, match=r"servo\.max_velocity must give one value per joint"):
        _run(small_traj, robot, max_velocity=(1.0, 1.0))
