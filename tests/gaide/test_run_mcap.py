"""``run.mcap``: written from tiny inputs (each part checked against its reference: the
forward kinematics against Pinocchio's frame poses, the sphere markers against the collision
checker's centres), with inputs missing, atomically, and by a real ``gaide run`` (its topics,
counts and stamps against the run's other files).

Files are read back with the ``mcap`` reader and decoded with rosbags' typestore, as a tool
that knows nothing of this project would.
"""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore

from execution.trajectory import TimedTrajectory
from gaide.pipeline import run_mcap as rm
from gaide.pipeline.run_mcap import write_run_mcap
from gaide_core.camera import Intrinsics
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates
from gaide_core.transforms import from_xyz_quat
from perception.frames import BagLayout, Frames, ImageStream
from planning.checker import make_checker
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel
from tests.gaide.conftest import GOAL

TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)
START_NS = 1_700_000_000_000_000_000
ALL_TOPICS = {
    rm.COLOR_IMAGE: "sensor_msgs/msg/CompressedImage",
    rm.COLOR_INFO: "sensor_msgs/msg/CameraInfo",
    rm.DEPTH_IMAGE: "sensor_msgs/msg/Image",
    rm.DEPTH_INFO: "sensor_msgs/msg/CameraInfo",
    rm.CLOUD: "sensor_msgs/msg/PointCloud2",
    rm.TF: "tf2_msgs/msg/TFMessage",
    rm.TF_STATIC: "tf2_msgs/msg/TFMessage",
    rm.SPHERES: "visualization_msgs/msg/MarkerArray",
    rm.PATH: "nav_msgs/msg/Path",
    rm.TRAJECTORY: "trajectory_msgs/msg/JointTrajectory",
    rm.PLANNED_STATES: "sensor_msgs/msg/JointState",
    rm.SIMULATED_STATES: "sensor_msgs/msg/JointState",
}


class Read:
    """A run.mcap read back: per topic, (log time, publish time, decoded message)."""

    def __init__(self, path: Path) -> None:
        self.messages: dict[str, list[tuple[int, int, Any]]] = defaultdict(list)
        self.types: dict[str, str] = {}
        with path.open("rb") as f:
            reader = make_reader(f)
            assert reader.get_header().profile == "ros2"
            for schema, channel, message in reader.iter_messages():
                assert schema is not None
                assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
                # the schema is the full definition text (with its dependencies)
                assert schema.data.decode().strip(), schema.name
                self.types[channel.topic] = schema.name
                msg = TYPESTORE.deserialize_cdr(message.data, schema.name)
                self.messages[channel.topic].append((message.log_time, message.publish_time, msg))

    def counts(self) -> dict[str, int]:
        return {topic: len(v) for topic, v in self.messages.items()}

    def msgs(self, topic: str) -> list[Any]:
        return [m for _, _, m in self.messages[topic]]

    def times(self, topic: str) -> list[int]:
        return [t for t, _, _ in self.messages[topic]]

    def check_stamps(self) -> None:
        """Log times increase on every topic; publish times and header stamps equal them."""
        for topic, items in self.messages.items():
            logs = [t for t, _, _ in items]
            assert logs == sorted(logs), topic
            for log_time, publish_time, msg in items:
                assert publish_time == log_time, topic
                for stamp in _header_stamps(msg):
                    assert stamp == log_time, topic


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _header_stamps(msg: Any) -> list[int]:
    """Every header stamp in a message (its own, its transforms', markers', poses')."""
    stamps = [_ns(msg.header.stamp)] if hasattr(msg, "header") else []
    for items in ("transforms", "markers", "poses"):
        stamps += [_ns(m.header.stamp) for m in getattr(msg, items, [])]
    return stamps


def _pose(tf: Any) -> np.ndarray:
    t, r = tf.transform.translation, tf.transform.rotation
    return from_xyz_quat([t.x, t.y, t.z], [r.x, r.y, r.z, r.w])


def _chain(transforms: list[Any], root: str, frame: str) -> np.ndarray:
    """``frame``'s pose in ``root`` composed along the TF tree of one message."""
    by_child = {tf.child_frame_id: tf for tf in transforms}
    T = np.eye(4)
    while frame != root:
        tf = by_child[frame]
        T = _pose(tf) @ T
        frame = tf.header.frame_id
    return T


# -- tiny inputs -------------------------------------------------------------------------


def _frames(n: int = 2) -> Frames:
    rng = np.random.default_rng(3)
    K = np.array([[20.0, 0, 8], [0, 20.0, 6], [0, 0, 1]])
    stamps = START_NS + np.arange(n, dtype=np.int64) * 33_333_333
    color = ImageStream(
        Intrinsics(16, 12, K),
        tuple(rng.integers(0, 255, (12, 16, 3), dtype=np.uint8) for _ in range(n)),
        stamps,
        "0",  # as SDK recordings name both streams' frames
    )
    depth = ImageStream(
        Intrinsics(16, 12, K.copy()),
        tuple(rng.integers(300, 3000, (12, 16), dtype=np.uint16) for _ in range(n)),
        stamps + 1_000_000,
        "0",
    )
    T_color_depth = from_xyz_quat([-0.015, 0, 0], [0, 0, 0, 1])
    return Frames(Path("tiny.bag"), BagLayout.SDK, depth, color, 0.001, T_color_depth)


def _trajectory(robot: RobotModel, path: np.ndarray, rate_hz: float) -> TimedTrajectory:
    """Linear in joint space through ``path``, one edge per second, at ``rate_hz``."""
    n = round(rate_hz * (len(path) - 1)) + 1
    t = np.arange(n) / rate_hz
    s = np.linspace(0, len(path) - 1, n)
    i = np.minimum(s.astype(int), len(path) - 2)
    q = path[i] + (s - i)[:, None] * (path[i + 1] - path[i])
    qd = np.gradient(q, t, axis=0)
    return TimedTrajectory(
        t=t,
        q=q,
        qd=qd,
        qdd=np.gradient(qd, t, axis=0),
        joint_names=robot.joint_names,
        rate_hz=rate_hz,
        path=path,
    )


def _path(robot: RobotModel) -> np.ndarray:
    home = robot.named_configuration("home")
    steps = np.array([[0, 0, 0, 0, 0, 0], [0.4, -0.2, 0.3, 0, 0.2, 0.1], [0.8, 0, 0.1, 0, 0, 0]])
    return home + steps


def _inputs(robot: RobotModel, spheres: SphereModel, rate_hz: float = 50.0) -> dict[str, Any]:
    rng = np.random.default_rng(4)
    path = _path(robot)
    traj = _trajectory(robot, path, rate_hz)
    sim_t = np.arange(len(traj.t) + 5) / rate_hz  # the simulation settles a little longer
    sim_q = np.vstack([traj.q, np.repeat(traj.q[-1:], 5, axis=0)]) + 1e-4
    return {
        "start_ns": START_NS,
        "frames": _frames(),
        "cloud_points": rng.uniform(-1, 1, (50, 3)),
        "cloud_colors": rng.uniform(0, 1, (50, 3)),
        "T_base_cam": from_xyz_quat([1.1, -0.7, 0.6], [0.6, -0.5, 0.35, -0.45]),
        "robot": robot,
        "spheres": spheres,
        "path_q": path,
        "trajectory": traj,
        "simulated": JointStates(names=robot.joint_names, t=sim_t, q=sim_q, start_ns=123),
    }


def test_every_part_reads_back_with_its_schema_and_matches_its_reference(
    tmp_path: Path, robot: RobotModel, spheres: SphereModel
) -> None:
    kw = _inputs(robot, spheres)
    traj: TimedTrajectory = kw["trajectory"]
    written = write_run_mcap(tmp_path / "run.mcap", **kw)
    got = Read(tmp_path / "run.mcap")
    assert got.types == ALL_TOPICS
    n = len(traj.t)
    assert (
        got.counts()
        == written.topics
        == {
            rm.COLOR_IMAGE: 2,
            rm.COLOR_INFO: 2,
            rm.DEPTH_IMAGE: 2,
            rm.DEPTH_INFO: 2,
            rm.CLOUD: 1,
            rm.TF_STATIC: 1,
            rm.PATH: 1,
            rm.TRAJECTORY: 1,
            rm.PLANNED_STATES: n,  # every sample
            rm.TF: n,  # 50 Hz: under max_rate_hz, every sample
            rm.SPHERES: n,
            rm.SIMULATED_STATES: n + 5,
        }
    )
    got.check_stamps()
    assert written.size_bytes == (tmp_path / "run.mcap").stat().st_size
    assert not [p for p in tmp_path.iterdir() if p.name != "run.mcap"]  # no temporary left

    # The trajectory's clock: time 0 at start_ns, every sample at start_ns + t.
    expected = (START_NS + np.rint(traj.t * 1e9).astype(np.int64)).tolist()
    assert got.times(rm.PLANNED_STATES) == expected == got.times(rm.TF) == got.times(rm.SPHERES)
    assert expected[-1] - expected[0] == round(traj.duration * 1e9)
    sim = got.msgs(rm.SIMULATED_STATES)
    assert got.times(rm.SIMULATED_STATES)[0] == START_NS  # its own start_ns is not the run's
    np.testing.assert_allclose(sim[0].position, kw["simulated"].q[0])
    states = got.msgs(rm.PLANNED_STATES)
    assert list(states[7].name) == list(robot.joint_names)
    np.testing.assert_allclose(states[7].position, traj.q[7])
    np.testing.assert_allclose(states[7].velocity, traj.qd[7])
    (jt,) = got.msgs(rm.TRAJECTORY)
    assert len(jt.points) == n and list(jt.joint_names) == list(robot.joint_names)
    assert _ns(jt.points[-1].time_from_start) == round(traj.duration * 1e9)
    np.testing.assert_allclose(jt.points[-1].accelerations, traj.qdd[-1])

    # /tf: every link, and the end effector composed along the tree is Pinocchio's pose.
    (static,) = got.msgs(rm.TF_STATIC)
    np.testing.assert_allclose(_chain(static.transforms, "world", rm.COLOR_FRAME), kw["T_base_cam"])
    np.testing.assert_allclose(
        _chain(static.transforms, "world", rm.DEPTH_FRAME),
        kw["T_base_cam"] @ kw["frames"].T_color_depth,
        atol=1e-12,
    )
    tfs = got.msgs(rm.TF)
    children = {tf.child_frame_id for tf in tfs[0].transforms}
    assert children == set(robot.links) - {"world"}  # the UR5's root link is the fixed frame
    checker = make_checker(robot, spheres)
    for i in (0, n // 2, n - 1):
        for link in ("tool0", "forearm_link"):
            np.testing.assert_allclose(
                _chain(tfs[i].transforms, "world", link),
                robot.frame_pose(traj.q[i], link),
                atol=1e-9,
            )
        # sphere markers: one per sphere, at the checker's centres, with its radius
        markers = got.msgs(rm.SPHERES)[i].markers
        assert [m.ns for m in markers] == list(spheres.links)
        centres = np.array(
            [[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in markers]
        )
        np.testing.assert_allclose(centres, checker.sphere_centers(traj.q[i : i + 1])[0], atol=1e-9)
        np.testing.assert_allclose([m.scale.x for m in markers], 2 * spheres.radii)
        assert {m.type for m in markers} == {2} and {m.header.frame_id for m in markers} == {
            "world"
        }

    # the planned path: the end effector from the first waypoint to the last
    (path,) = got.msgs(rm.PATH)
    assert len(path.poses) > len(kw["path_q"])  # densified along the edges
    for pose, q in ((path.poses[0], kw["path_q"][0]), (path.poses[-1], kw["path_q"][-1])):
        p, o = pose.pose.position, pose.pose.orientation
        np.testing.assert_allclose(
            from_xyz_quat([p.x, p.y, p.z], [o.x, o.y, o.z, o.w]), robot.frame_pose(q), atol=1e-9
        )

    # the cloud: every point, its colour packed as rgb
    (cloud,) = got.msgs(rm.CLOUD)
    assert cloud.header.frame_id == "world" and cloud.width == 50 and cloud.height == 1
    assert [f.name for f in cloud.fields] == ["x", "y", "z", "rgb"]
    dtype = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<u4")])
    pts = np.frombuffer(bytes(cloud.data), dtype=dtype)
    np.testing.assert_allclose(np.c_[pts["x"], pts["y"], pts["z"]], kw["cloud_points"], atol=1e-6)
    rgb = np.c_[(pts["rgb"] >> 16) & 255, (pts["rgb"] >> 8) & 255, pts["rgb"] & 255] / 255
    np.testing.assert_allclose(rgb, kw["cloud_colors"], atol=0.5 / 255 + 1e-9)

    # images: depth bytes unchanged (16UC1, mm), color a JPEG of the image's size
    frames: Frames = kw["frames"]
    assert frames.depth is not None and frames.color is not None
    depth = got.msgs(rm.DEPTH_IMAGE)[1]
    assert (depth.encoding, depth.width, depth.height, depth.step) == ("16UC1", 16, 12, 32)
    np.testing.assert_array_equal(
        np.frombuffer(bytes(depth.data), "<u2").reshape(12, 16), frames.depth.images[1]
    )
    assert got.times(rm.DEPTH_IMAGE) == frames.depth.stamps_ns.tolist()
    import cv2

    color = got.msgs(rm.COLOR_IMAGE)[0]
    assert color.format == "jpeg" and color.header.frame_id == rm.COLOR_FRAME
    decoded = cv2.imdecode(np.asarray(color.data, np.uint8), cv2.IMREAD_COLOR)
    assert decoded is not None and decoded.shape == (12, 16, 3)
    info = got.msgs(rm.COLOR_INFO)[0]
    np.testing.assert_allclose(np.reshape(info.k, (3, 3)), frames.color.intrinsics.K)
    assert (info.width, info.height) == (16, 12)


def test_tf_and_spheres_are_subsampled_to_the_max_rate_and_keep_the_last_sample(
    tmp_path: Path, robot: RobotModel, spheres: SphereModel
) -> None:
    kw = _inputs(robot, spheres, rate_hz=500.0)
    traj: TimedTrajectory = kw["trajectory"]
    written = write_run_mcap(tmp_path / "run.mcap", **kw, max_rate_hz=100.0)
    got = Read(tmp_path / "run.mcap")
    assert got.counts()[rm.PLANNED_STATES] == len(traj.t)  # joint states keep every sample
    times = np.array(got.times(rm.TF))
    assert got.times(rm.SPHERES) == times.tolist()
    assert times[0] == START_NS and times[-1] == START_NS + round(traj.duration * 1e9)
    assert np.diff(times).max() == 10_000_000  # 100 Hz
    assert len(times) == len(rm.sample_indices(len(traj.t), 500.0, 100.0)) == 201
    assert written.tf_rate_hz == pytest.approx(100.0)


def test_missing_parts_are_left_out(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    sim = JointStates(
        names=("a", "b"), t=np.array([0.0, 0.01, 0.02, 0.03]), q=rng.normal(size=(4, 2))
    )
    out = tmp_path / "run.mcap"
    written = write_run_mcap(
        out, start_ns=5_000, cloud_points=rng.uniform(size=(7, 3)), simulated=sim
    )
    got = Read(out)
    assert got.counts() == written.topics == {rm.CLOUD: 1, rm.SIMULATED_STATES: 4}
    got.check_stamps()
    (cloud,) = got.msgs(rm.CLOUD)
    assert [f.name for f in cloud.fields] == ["x", "y", "z"] and cloud.point_step == 12
    assert got.times(rm.SIMULATED_STATES) == [5_000, 10_005_000, 20_005_000, 30_005_000]

    # only a camera pose and depth: the depth camera is the camera the pose places
    frames = _frames(1)
    depth_only = Frames(frames.source, frames.layout, frames.depth, None, 0.0001, None)
    write_run_mcap(out, start_ns=5_000, frames=depth_only, T_base_cam=np.eye(4))
    got = Read(out)
    assert set(got.counts()) == {rm.DEPTH_IMAGE, rm.DEPTH_INFO, rm.TF_STATIC}
    (static,) = got.msgs(rm.TF_STATIC)
    assert [tf.child_frame_id for tf in static.transforms] == [rm.DEPTH_FRAME]
    depth = got.msgs(rm.DEPTH_IMAGE)[0]  # 0.1 mm units: metres as float32
    assert depth.encoding == "32FC1" and depth.step == 16 * 4
    assert depth_only.depth is not None
    np.testing.assert_allclose(
        np.frombuffer(bytes(depth.data), "<f4").reshape(12, 16),
        depth_only.depth.images[0] * 1e-4,
        rtol=1e-6,
    )


def test_refusals_and_failures_leave_nothing_half_written(
    tmp_path: Path, robot: RobotModel, spheres: SphereModel, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "run.mcap"
    with pytest.raises(ExecutionError, match="nothing to write"):
        write_run_mcap(out, start_ns=0)
    kw = _inputs(robot, spheres)
    with pytest.raises(ExecutionError, match="need the robot model"):
        write_run_mcap(out, start_ns=0, trajectory=kw["trajectory"])
    assert not list(tmp_path.iterdir())

    out.write_bytes(b"an earlier run.mcap")
    from mcap.writer import Writer

    add_message = Writer.add_message
    calls = 0

    def failing(self: Writer, *args: Any, **kwargs: Any) -> None:
        nonlocal calls
        calls += 1
        if calls > 20:  # part of the file is written by then
            raise ValueError("disk trouble")
        add_message(self, *args, **kwargs)

    monkeypatch.setattr(Writer, "add_message", failing)
    with pytest.raises(ExecutionError, match=r"run\.mcap: writing .* disk trouble"):
        write_run_mcap(out, **kw)
    assert out.read_bytes() == b"an earlier run.mcap"
    assert [p.name for p in tmp_path.iterdir()] == ["run.mcap"]


# -- a real run --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def run_folder(run_out: tuple[Path, str]) -> Path:
    out, stdout = run_out
    assert str(out / "run.mcap") in stdout  # the CLI says where it is
    return out


def test_a_run_writes_run_mcap_of_all_its_stages(run_folder: Path) -> None:
    from execution.joint_log import read_log_csv
    from execution.trajectory_io import read_trajectory

    summary = json.loads((run_folder / "summary.json").read_text())
    report = summary["stages"]["report"]
    assert str(run_folder / "run.mcap") in report["outputs"]
    got = Read(run_folder / "run.mcap")
    assert got.types == ALL_TOPICS
    assert got.counts() == report["figures"]["mcap"]["topics"]
    got.check_stamps()
    traj = read_trajectory(run_folder / "trajectory.csv")
    sim = read_log_csv(run_folder / "sim_log.csv")
    counts = got.counts()
    assert counts[rm.PLANNED_STATES] == counts[rm.TF] == counts[rm.SPHERES] == len(traj.t)
    assert counts[rm.SIMULATED_STATES] == len(sim.t)
    assert counts[rm.COLOR_IMAGE] == counts[rm.DEPTH_IMAGE] == 2  # the frames the bag holds
    (cloud,) = got.msgs(rm.CLOUD)
    assert cloud.width == summary["stages"]["perception"]["figures"]["points"]
    assert "rgb" in [f.name for f in cloud.fields]
    # time 0 of the trajectory is the first image's stamp; /tf spans the trajectory
    start = min(got.times(rm.COLOR_IMAGE)[0], got.times(rm.DEPTH_IMAGE)[0])
    tf = got.times(rm.TF)
    assert tf[0] == start and tf[-1] - tf[0] == round(traj.duration * 1e9)
    assert got.times(rm.SIMULATED_STATES)[0] == start
    (static,) = got.msgs(rm.TF_STATIC)
    calib = summary["stages"]["calibration"]["figures"]
    camera = _chain(static.transforms, "world", static.transforms[0].child_frame_id)
    np.testing.assert_allclose(camera[:3, 3], calib["T_base_cam_xyz"], atol=1e-5)
    (jt,) = got.msgs(rm.TRAJECTORY)
    np.testing.assert_allclose(np.array([p.positions for p in jt.points]), traj.q, atol=1e-9)


def test_a_failed_run_writes_what_its_stages_made(
    bag: Path, run_folder: Path, tmp_path: Path
) -> None:
    from gaide.pipeline.config_io import load_cfg
    from gaide.pipeline.run import run_pipeline
    from gaide_core.errors import PlanningError

    out = tmp_path / "failed"
    cfg = load_cfg(
        overrides=[
            ("bag", str(bag)), ("out", str(out)), ("planning.goal", GOAL),
            ("planning.start", "0,0.5,0,0,0,0"),  # in collision: planning fails
            ("calibration.calib", str(run_folder / "calibration.yaml")),
            ("planning.planner", "rrtc"),
        ]
    )  # fmt: skip
    with pytest.raises(PlanningError):
        run_pipeline(cfg)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failed_stage"] == "planning"
    assert str(out / "run.mcap") in summary["stages"]["report"]["outputs"]
    got = Read(out / "run.mcap")
    assert set(got.counts()) == {
        rm.COLOR_IMAGE, rm.COLOR_INFO, rm.DEPTH_IMAGE, rm.DEPTH_INFO, rm.CLOUD, rm.TF_STATIC
    }  # fmt: skip
    got.check_stamps()
