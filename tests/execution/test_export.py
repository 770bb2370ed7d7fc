from __future__ import annotations

import dataclasses
import logging
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from execution.export import read_log, write_log, write_trajectory
from execution.limits import JointLimits
from execution.ros2_goal import MAX_ARG_BYTES, Ros2GoalCfg, goal_points, goal_yaml
from execution.ros_bags import read_trajectory_bag
from execution.trajectory import TimedTrajectory
from execution.trajectory_io import read_trajectory
from execution.urscript import (
    UR_JOINTS,
    UrScriptCfg,
    UrScriptMode,
    blend_radii,
    quintic_hermite,
    servo_period,
    servo_samples,
    ur_order,
    urscript_program,
)
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


#: name, contents (None: no file) -> what the refusal says
BAD_TRAJECTORIES = {
    "t.csv": (None, "does not exist"),
    "t.txt": ("t,a_pos\n0,1\n", "must be a .csv or .json file"),
    "header-only.csv": ("t,a_pos,a_vel,a_acc\n", "a header row and at least one data row"),
    "no-t.csv": ("x,a_pos,a_vel,a_acc\n0,1,0,0\n", "the first column must be 't'"),
    "no-pos.csv": ("t,a_vel\n0,0\n0.01,0\n", "no '<joint>_pos' columns"),
    "no-acc.csv": ("t,a_pos,a_vel\n0,1,2\n", "missing columns ['a_acc']"),
    "text.csv": ("t,a_pos,a_vel,a_acc\n0,one,0,0\n", "a value is not a number"),
    "short-row.csv": ("t,a_pos,a_vel,a_acc\n0,1,0,0\n0.01,1\n", "every row needs 4 values"),
    "nan.csv": ("t,a_pos,a_vel,a_acc\n0,nan,0,0\n0.01,1,0,0\n", "contains NaN or inf"),
    "one-sample.csv": ("t,a_pos,a_vel,a_acc\n0,1,0,0\n", "needs at least 2 samples"),
    "uneven.csv": ("t,a_pos,a_vel,a_acc\n0,1,2,3\n0.01,1,2,3\n0.05,1,2,3\n", "equal steps"),
    "moving.csv": ("t,a_pos,a_vel,a_acc\n0,0,0,0\n0.01,0.01,1,0\n", "ends moving"),
    "not-ours.json": ('{"t": [0, 0.01]}', "not a trajectory file"),
}


@pytest.mark.parametrize("name", list(BAD_TRAJECTORIES))
def test_a_bad_trajectory_file_is_refused_by_name(name: str, tmp_path: Path) -> None:
    contents, says = BAD_TRAJECTORIES[name]
    path = tmp_path / name
    if contents is not None:
        path.write_text(contents)
    with pytest.raises(ExecutionError, match=re.escape(says)):
        read_trajectory(path)


# -- controller programs: URScript and the ros2_control goal ---------------------------------

SERVOJ = re.compile(
    r"^  servoj\(\[([^\]]*)\], 0, 0, ([0-9.]+), ([0-9.]+), ([0-9.]+)\)$", re.MULTILINE
)
MOVEJ = re.compile(r"^  movej\(\[([^\]]*)\], a=([0-9.]+), v=([0-9.]+)(?:, r=([0-9.]+))?\)$", re.M)
#: rad: positions are written with 10 decimals
WRITTEN = 5e-11


def _rows(matches: list[tuple[str, ...]]) -> np.ndarray:
    return np.array([[float(v) for v in m[0].split(",")] for m in matches])


def _shuffled(traj: TimedTrajectory, perm: list[int], prefix: str = "") -> TimedTrajectory:
    """``traj`` with its joints in another order (column j of the result is ``perm[j]``)."""
    assert traj.limits is not None and traj.path is not None
    lim = traj.limits
    names = tuple(prefix + traj.joint_names[j] for j in perm)
    return TimedTrajectory(
        t=traj.t,
        q=traj.q[:, perm],
        qd=traj.qd[:, perm],
        qdd=traj.qdd[:, perm],
        joint_names=names,
        rate_hz=traj.rate_hz,
        path=traj.path[:, perm],
        limits=JointLimits(
            names=names,
            **{k: getattr(lim, k)[perm] for k in ("lower", "upper", "velocity", "acceleration")},
            jerk=lim.jerk[perm],
        ),
    )


def test_servoj_streams_one_target_per_sample_and_ends_at_the_end(
    small_traj: TimedTrajectory, tmp_path: Path
) -> None:
    (out,) = write_trajectory(small_traj, [tmp_path / "t.script"])
    program = out.read_text()
    lines = program.splitlines()
    assert lines[0] == "def gaide_trajectory():"
    assert lines[-2:] == ["end", "gaide_trajectory()"]
    # the first motion is a movej to the start at the approach speed, nothing before it
    first = MOVEJ.search(program)
    assert first is not None and first.start() < program.index("servoj(")
    np.testing.assert_allclose(_rows([first.groups()]), small_traj.q[:1], atol=WRITTEN)
    cfg = UrScriptCfg()
    assert (float(first[2]), float(first[3])) == (cfg.approach_acceleration, cfg.approach_speed)
    assert first[4] is None  # the robot stops at the start
    streamed = SERVOJ.findall(program)
    assert len(streamed) == len(small_traj.t)  # one per sample, the trajectory's own (100 Hz)
    assert {m[1:] for m in streamed} == {("0.01", "0.03", "2000.0")}
    q = _rows(streamed)
    np.testing.assert_allclose(q, small_traj.q, atol=WRITTEN)
    np.testing.assert_allclose(q[-1], small_traj.q[-1], atol=WRITTEN)  # the end exactly
    # the end is held, then the joints stop
    assert "  q_end = [" in program and "    servoj(q_end, 0, 0, 0.01, 0.03, 2000.0)" in lines
    assert lines[-3].startswith("  stopj(")


@pytest.mark.parametrize("period", [0.002, 0.008])
def test_servoj_resamples_at_a_chosen_period(small_traj: TimedTrajectory, period: float) -> None:
    cfg = UrScriptCfg(servoj_period_s=period)
    streamed = SERVOJ.findall(urscript_program(small_traj, cfg))
    steps = int(np.ceil(small_traj.duration / period - 1e-9))
    assert len(streamed) == steps + 1
    assert {float(m[1]) for m in streamed} == {period}
    assert steps * period >= small_traj.duration > (steps - 1) * period
    q = _rows(streamed)
    assert small_traj.chain is not None
    times = np.minimum(np.arange(steps + 1) * period, small_traj.chain.duration)
    np.testing.assert_allclose(q, small_traj.chain.evaluate(times)[0], atol=WRITTEN)
    np.testing.assert_allclose(q[-1], small_traj.q[-1], atol=WRITTEN)
    # Read back from a file the trajectory has no Ruckig segments: the quintic spline through
    # its samples stays within 1e-6 rad of them (jerk-limited pieces between 10 ms samples).
    from_file = dataclasses.replace(small_traj, chain=None)
    spline = servo_samples(from_file, period)
    np.testing.assert_allclose(spline, q, atol=1e-6)
    np.testing.assert_array_equal(spline[-1], small_traj.q[-1])


def test_servoj_period_is_whole_control_cycles(small_traj: TimedTrajectory) -> None:
    assert servo_period(small_traj, UrScriptCfg()) == pytest.approx(0.01)
    # 300 Hz is 3.33 ms: rounded up to two 2 ms cycles
    assert servo_period(dataclasses.replace(small_traj, rate_hz=300.0), UrScriptCfg()) == 0.004
    with pytest.raises(ExecutionError, match=r"servoj_period_s must be a whole number of 0\.002"):
        UrScriptCfg(servoj_period_s=0.003)
    with pytest.raises(ExecutionError, match=r"servoj_lookahead_s must be a number in \[0\.03"):
        UrScriptCfg(servoj_lookahead_s=0.5)
    with pytest.raises(ExecutionError, match=r"urscript_mode must be one of \['servoj', 'movej'\]"):
        UrScriptCfg(urscript_mode="speedj")  # type: ignore[arg-type]


@pytest.mark.parametrize("prefix", ["", "ur_"])
def test_urscript_maps_the_joints_to_the_ur_order(small_traj: TimedTrajectory, prefix: str) -> None:
    perm = [3, 0, 5, 1, 4, 2]
    shuffled = _shuffled(small_traj, perm, prefix)
    assert list(ur_order(shuffled.joint_names)) == [1, 3, 5, 0, 4, 2]
    streamed = SERVOJ.findall(urscript_program(shuffled))
    # the UR5 config names its joints in UR's order: the program is the unshuffled one
    np.testing.assert_allclose(_rows(streamed), small_traj.q, atol=WRITTEN)
    moves = MOVEJ.findall(
        urscript_program(shuffled, UrScriptCfg(urscript_mode=UrScriptMode.MOVEJ, blend_radius_m=0))
    )
    assert small_traj.path is not None
    np.testing.assert_allclose(_rows(moves), small_traj.path, atol=WRITTEN)


@pytest.mark.parametrize(
    "names",
    [
        ("a", "b", "c", "d", "e", "f"),
        (*UR_JOINTS[:5], "elbow_joint"),  # one twice, one missing
        ("l_" + UR_JOINTS[0], "r_" + UR_JOINTS[1], *UR_JOINTS[2:]),  # two prefixes
    ],
)
def test_urscript_refuses_other_joints_and_writes_nothing(
    small_traj: TimedTrajectory, tmp_path: Path, names: tuple[str, ...]
) -> None:
    other = dataclasses.replace(small_traj, joint_names=names, limits=None, chain=None)
    with pytest.raises(ExecutionError, match=r"UR's six joints .* the trajectory's joints are \['"):
        write_trajectory(other, [tmp_path / "t.csv", tmp_path / "t.script"])
    assert list(tmp_path.iterdir()) == []
    for count in (UR_JOINTS[:5], (*UR_JOINTS, "gripper_joint")):
        with pytest.raises(ExecutionError, match="UR's six joints"):
            ur_order(count)


def test_movej_blends_never_overlap_and_stop_at_the_goal(
    small_traj: TimedTrajectory, robot: RobotModel, tmp_path: Path
) -> None:
    assert small_traj.path is not None and small_traj.limits is not None
    path = small_traj.path
    tool = np.array([robot.frame_pose(q)[:3, 3] for q in path])
    gaps = np.linalg.norm(np.diff(tool, axis=0), axis=1)  # m, between consecutive waypoints
    for r_max in (0.01, 1.0):  # 1 m: every radius is clipped
        cfg = UrScriptCfg(urscript_mode=UrScriptMode.MOVEJ, blend_radius_m=r_max)
        (out,) = write_trajectory(small_traj, [tmp_path / "m.script"], urscript=cfg, robot=robot)
        start, *moves = MOVEJ.findall(out.read_text())
        assert "servoj" not in out.read_text()
        np.testing.assert_allclose(_rows([start, *moves]), path, atol=WRITTEN)
        r = np.array([0.0, *(float(m[3]) for m in moves)])  # the start: a plain stop
        assert r[-1] == 0.0 and np.all(r <= r_max)
        assert np.all(r[:-1] + r[1:] <= gaps)  # no blend overlaps its neighbour's
        assert r[1:-1].min() > 0  # every inner waypoint is blended
        if r_max == 1.0:
            assert np.all(r[1:-1] < r_max)
            np.testing.assert_allclose(r, blend_radii(tool, r_max))
        # at the trajectory's limits: the smallest joint's, as UR's a and v are the leading axis's
        assert {(float(m[1]), float(m[2])) for m in moves} == {
            (small_traj.limits.acceleration.min(), small_traj.limits.velocity.min())
        }
    with pytest.raises(ExecutionError, match="blend radii need the tool's positions"):
        urscript_program(small_traj, UrScriptCfg(urscript_mode=UrScriptMode.MOVEJ))
    with pytest.raises(ExecutionError, match="movej needs the trajectory's waypoints"):
        urscript_program(dataclasses.replace(small_traj, path=None), cfg, tool_xyz=tool)


def test_a_trajectory_of_another_robot_is_refused_before_writing(
    small_traj: TimedTrajectory, robot: RobotModel, tmp_path: Path
) -> None:
    perm = [1, 0, 2, 3, 4, 5]  # UR joints all the same, in another order than the robot's
    with pytest.raises(ExecutionError, match=r"joints \['shoulder_lift_joint', .* not the robot's"):
        write_trajectory(_shuffled(small_traj, perm), [tmp_path / "t.csv"], robot=robot)
    assert list(tmp_path.iterdir()) == []


def _duration_ns(d: dict[str, int]) -> int:
    assert set(d) == {"sec", "nanosec"} and 0 <= d["nanosec"] < 10**9
    return d["sec"] * 10**9 + d["nanosec"]


@pytest.mark.parametrize("rate", [50.0, 100.0])
def test_the_ros2_goal_holds_the_trajectory_samples(
    small_traj: TimedTrajectory, tmp_path: Path, rate: float
) -> None:
    cfg = Ros2GoalCfg(ros2_controller="scaled_joint_trajectory_controller", goal_rate_hz=rate)
    (out,) = write_trajectory(small_traj, [tmp_path / "goal.yaml"], goal=cfg)
    text = out.read_text()
    assert text.splitlines()[0] == (
        "# ros2 action send_goal /scaled_joint_trajectory_controller/follow_joint_trajectory "
        'control_msgs/action/FollowJointTrajectory "$(cat goal.yaml)"'
    )
    goal = yaml.safe_load(text)
    assert set(goal) == {"trajectory", "goal_time_tolerance"}
    assert _duration_ns(goal["goal_time_tolerance"]) == 500_000_000
    assert goal["trajectory"]["joint_names"] == list(small_traj.joint_names)
    points = goal["trajectory"]["points"]
    idx = goal_points(small_traj, rate)
    step = 2 if rate == 50.0 else 1  # 100 Hz samples
    np.testing.assert_array_equal(
        idx[:-1], np.arange(0, len(small_traj.t) - 1, step)[: len(idx) - 1]
    )
    assert idx[-1] == len(small_traj.t) - 1 and len(points) == len(idx)
    for p, i in zip(points, idx, strict=True):
        assert set(p) == {"positions", "velocities", "accelerations", "time_from_start"}
        # the shortest round-trip numbers: the samples exactly
        np.testing.assert_array_equal(p["positions"], small_traj.q[i])
        np.testing.assert_array_equal(p["velocities"], small_traj.qd[i])
        np.testing.assert_array_equal(p["accelerations"], small_traj.qdd[i])
        assert _duration_ns(p["time_from_start"]) == round(small_traj.t[i] * 1e9)
    assert _duration_ns(points[-1]["time_from_start"]) == round(small_traj.duration * 1e9)
    # The controller's quintic splines through the points follow the trajectory closely.
    t = np.array([_duration_ns(p["time_from_start"]) for p in points]) * 1e-9
    q, qd, qdd = (
        np.array([p[k] for p in points]) for k in ("positions", "velocities", "accelerations")
    )
    np.testing.assert_allclose(
        quintic_hermite(t, q, qd, qdd, small_traj.t), small_traj.q, atol=2e-6
    )


def test_the_ros2_goal_is_yaml_floats_and_warns_past_one_shell_argument(
    caplog: pytest.LogCaptureFixture,
) -> None:
    n = 2000  # 4 s at 500 Hz, every sample: over 128 KiB
    q = np.zeros((n, 6))
    qd = np.full((n, 6), 1e-20)  # repr: 1e-20, which YAML 1.1 reads as a string
    traj = TimedTrajectory(
        t=np.arange(n) / 500.0, q=q, qd=qd, qdd=-qd, joint_names=UR_JOINTS, rate_hz=500.0
    )
    with caplog.at_level(logging.WARNING, logger="execution.ros2_goal"):
        text = goal_yaml(traj, Ros2GoalCfg(goal_rate_hz=500.0), file_name="long goal.yaml")
    assert len(text.encode()) > MAX_ARG_BYTES
    assert "lower goal_rate_hz (`gaide time --goal-rate`) to " in caplog.text
    assert "\"$(cat 'long goal.yaml')\"" in text.splitlines()[0]
    point = yaml.safe_load(text)["trajectory"]["points"][1]
    assert point["velocities"] == [1e-20] * 6 and point["accelerations"] == [-1e-20] * 6
    assert _duration_ns(point["time_from_start"]) == 2_000_000
    with pytest.raises(ExecutionError, match="ros2_controller must be a ROS name"):
        Ros2GoalCfg(ros2_controller="my controller")
