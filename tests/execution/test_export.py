from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from execution.export import read_log, write_log, write_trajectory
from execution.ros_bags import read_trajectory_bag
from execution.trajectory import TimedTrajectory
from execution.trajectory_io import read_trajectory
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates
from planning.robot_model import RobotModel


def test_csv_and_json_round_trip(small_traj: TimedTrajectory, tmp_path: Path) -> None:
    csv, js = write_trajectory(small_traj, [tmp_path / "t.csv", tmp_path / "t.json"])
    header = csv.read_text().splitlines()[0].split(",")
    assert header[:2] == ["t", "shoulder_pan_joint_pos"]
    assert "wrist_3_joint_vel" in header and "elbow_joint_acc" in header
    assert "wrist_1_joint_jerk" in header
    for path in (csv, js):
        back = read_trajectory(path)
        assert back.joint_names == small_traj.joint_names
        assert back.rate_hz == pytest.approx(100.0)
        for attr in ("t", "q", "qd", "qdd", "jerk"):
            np.testing.assert_allclose(getattr(back, attr), getattr(small_traj, attr), atol=1e-15)
    back = read_trajectory(js)
    assert back.mode is small_traj.mode and back.status is small_traj.status
    assert back.path is not None and small_traj.path is not None
    np.testing.assert_array_equal(back.path, small_traj.path)
    assert back.segments == small_traj.segments
    assert back.limits is not None and back.limits.names == small_traj.joint_names


@pytest.mark.parametrize(
    ("name", "storage", "store"),
    [
        ("t.bag", "sqlite3", Stores.ROS1_NOETIC),
        ("t_ros2", "sqlite3", Stores.ROS2_HUMBLE),
        ("t_mcap", "mcap", Stores.ROS2_HUMBLE),
    ],
)
def test_bags_hold_one_joint_trajectory_with_the_urdf_joint_names(
    small_traj: TimedTrajectory,
    robot: RobotModel,
    tmp_path: Path,
    name: str,
    storage: str,
    store: Stores,
) -> None:
    (out,) = write_trajectory(small_traj, [tmp_path / name], storage=storage)
    # Read with rosbags directly, as any ROS tool would.
    with AnyReader([out], default_typestore=get_typestore(store)) as reader:
        conns = [c for c in reader.connections if c.topic == "/joint_trajectory"]
        assert [c.msgtype for c in conns] == ["trajectory_msgs/msg/JointTrajectory"]
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]
    assert len(msgs) == 1
    msg = msgs[0]
    assert list(msg.joint_names) == list(robot.joint_names)
    assert len(msg.points) == len(small_traj.t)
    last = msg.points[-1]
    np.testing.assert_allclose(last.positions, small_traj.q[-1], atol=1e-15)
    np.testing.assert_allclose(msg.points[7].velocities, small_traj.qd[7], atol=1e-15)
    np.testing.assert_allclose(msg.points[7].accelerations, small_traj.qdd[7], atol=1e-15)
    t_last = last.time_from_start.sec + 1e-9 * last.time_from_start.nanosec
    assert t_last == pytest.approx(small_traj.duration, abs=1e-9)
    back = read_trajectory_bag(out)
    np.testing.assert_allclose(back.q, small_traj.q, atol=1e-15)
    np.testing.assert_allclose(back.t, small_traj.t, atol=1e-9)


def test_joint_state_logs_round_trip(small_traj: TimedTrajectory, tmp_path: Path) -> None:
    log = JointStates(
        names=small_traj.joint_names,
        t=small_traj.t,
        q=small_traj.q,
        qd=small_traj.qd,
        start_ns=1_700_000_000_123_456_789,
    )
    outs = write_log(log, [tmp_path / "l.csv", tmp_path / "l.bag", tmp_path / "l_ros2"])
    with AnyReader([outs[1]]) as reader:
        assert {c.msgtype for c in reader.connections} == {"sensor_msgs/msg/JointState"}
        stamps = [
            reader.deserialize(raw, c.msgtype).header.stamp for c, _, raw in reader.messages()
        ]
    assert stamps[0].sec * 10**9 + stamps[0].nanosec == log.start_ns
    for out in outs:
        back = read_log(out)
        assert back.names == log.names
        np.testing.assert_allclose(back.q, log.q, atol=1e-15)
        assert back.qd is not None
        np.testing.assert_allclose(back.qd, log.qd, atol=1e-15)  # type: ignore[arg-type]
        np.testing.assert_allclose(back.t, log.t, atol=1e-9)
    assert read_log(outs[1]).start_ns == log.start_ns


def test_a_failing_export_leaves_nothing(small_traj: TimedTrajectory, tmp_path: Path) -> None:
    good, bad = tmp_path / "t.csv", tmp_path / "t.xlsx"
    with pytest.raises(ExecutionError, match=r"unknown output format '\.xlsx'"):
        write_trajectory(small_traj, [good, bad])
    # A failure while writing, after the CSV was written: nothing is renamed into place.
    with pytest.raises(ExecutionError, match="storage must be one of"):
        write_trajectory(small_traj, [good, tmp_path / "bag2"], storage="bogus")
    # An output that cannot be created (a file where a folder should be): nothing either.
    blocker = tmp_path / "blocked"
    blocker.write_text("not a folder")
    with pytest.raises(ExecutionError):
        write_trajectory(small_traj, [good, blocker / "t.json"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blocked"]


def test_an_existing_output_is_replaced_whole(small_traj: TimedTrajectory, tmp_path: Path) -> None:
    out = tmp_path / "ros2"
    write_trajectory(small_traj, [out])
    write_trajectory(small_traj, [out])
    assert read_trajectory_bag(out).q.shape == small_traj.q.shape
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ros2"]


def test_a_bad_trajectory_file_is_refused(tmp_path: Path) -> None:
    bad = tmp_path / "t.csv"
    bad.write_text("t,a_pos,a_vel\n0,1,2\n")
    with pytest.raises(ExecutionError, match="missing columns"):
        read_trajectory(bad)
    bad.write_text("t,a_pos,a_vel,a_acc\n0,1,2,3\n0.01,1,2,3\n0.05,1,2,3\n")
    with pytest.raises(ExecutionError, match="equal steps"):
        read_trajectory(bad)
