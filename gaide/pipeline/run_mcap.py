"""``run.mcap``: the whole run as one MCAP file that Foxglove (or any ROS2 tool) opens.

Topics (ROS2 Humble types; each written only when what it shows exists):

- ``/camera/color/image_raw/compressed`` (``sensor_msgs/CompressedImage``, JPEG) and
  ``/camera/color/camera_info``; ``/camera/depth/image_rect_raw`` (``sensor_msgs/Image``:
  ``16UC1`` in mm when the bag's depth unit is 1 mm, else ``32FC1`` in m) and
  ``/camera/depth/camera_info``: the images perception used, at their recorded stamps;
- ``/scene/cloud`` (``sensor_msgs/PointCloud2``; ``x, y, z`` float32 m, and ``rgb`` packed
  as float32 when the cloud has colours): the scene cloud in the fixed frame, once;
- ``/tf_static`` (``tf2_msgs/TFMessage``): the color camera in the fixed frame (the
  calibration's ``T_base_cam``), the depth camera in the color camera;
- ``/tf``: every link of the robot in its parent link (Pinocchio's forward kinematics of the
  URDF) at the trajectory's samples, at most ``max_rate_hz`` (the last sample always);
- ``/robot/collision_spheres`` (``visualization_msgs/MarkerArray``, one SPHERE marker per
  collision sphere, namespace = its link): at the same samples as ``/tf``;
- ``/planned_path`` (``nav_msgs/Path``): the end effector along the planned path (its
  straight joint-space edges, densified), once;
- ``/joint_trajectory`` (``trajectory_msgs/JointTrajectory``): the timed trajectory, once;
- ``/joint_states_planned`` (``sensor_msgs/JointState``): every trajectory sample;
- ``/joint_states``: the simulated robot, every logged sample.

Clock: integer ns. Trajectory time 0 is ``start_ns`` (the pipeline takes the first image's
stamp); images keep their recorded stamps; every header stamp equals its message's log and
publish time. Frames: the fixed frame (``world``, or ``gaide_world`` when the URDF has a link
``world`` that is not at the fixed frame's origin) is the pipeline's base frame: the cloud,
``T_base_cam`` and the forward kinematics' poses are all in it.

Messages come from rosbags' typestore (:class:`gaide_core.ros.Messages`), serialized as CDR;
the file is written by the ``mcap`` package with one ``ros2msg`` schema per type (the
definition text rosbags generates), so tools decode every topic without this project. The
file is written to a temporary sibling and renamed into place.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
from rosbags.serde import SerdeError
from rosbags.typesys import TypesysError

from gaide_core.atomic import write_file_atomic
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates
from gaide_core.ros import BagMessage, Messages, joint_state_messages
from gaide_core.types import Array, IntArray
from perception.bag_builder import MessageBuilder

if TYPE_CHECKING:
    from execution.trajectory import TimedTrajectory
    from perception.frames import Frames
    from planning.robot_model import RobotModel
    from planning.sphere_model import SphereModel

COLOR_IMAGE = "/camera/color/image_raw/compressed"
COLOR_INFO = "/camera/color/camera_info"
DEPTH_IMAGE = "/camera/depth/image_rect_raw"
DEPTH_INFO = "/camera/depth/camera_info"
CLOUD = "/scene/cloud"
TF = "/tf"
TF_STATIC = "/tf_static"
SPHERES = "/robot/collision_spheres"
PATH = "/planned_path"
TRAJECTORY = "/joint_trajectory"
PLANNED_STATES = "/joint_states_planned"
SIMULATED_STATES = "/joint_states"

COLOR_FRAME = "camera_color_optical_frame"
DEPTH_FRAME = "camera_depth_optical_frame"
PATH_STEP_RAD = 0.05  # longest joint-space step (Euclidean) between poses of /planned_path
JPEG_QUALITY = 90
#: Sphere colours (RGB), one per link in the sphere model's order, cycling.
PALETTE = ((0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16))
SPHERE_ALPHA = 0.45

_TF = "tf2_msgs/msg/TFMessage"
_TRANSFORM = "geometry_msgs/msg/TransformStamped"
_IMAGE = "sensor_msgs/msg/Image"
_COMPRESSED = "sensor_msgs/msg/CompressedImage"
_INFO = "sensor_msgs/msg/CameraInfo"
_CLOUD = "sensor_msgs/msg/PointCloud2"
_FIELD = "sensor_msgs/msg/PointField"
_MARKERS = "visualization_msgs/msg/MarkerArray"
_MARKER = "visualization_msgs/msg/Marker"
_PATH = "nav_msgs/msg/Path"
_TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
_POINT = "trajectory_msgs/msg/JointTrajectoryPoint"


@dataclass(frozen=True)
class RunMcap:
    """What :func:`write_run_mcap` wrote."""

    path: Path
    topics: dict[str, int]  # topic -> messages written
    types: dict[str, str]  # topic -> message type (``sensor_msgs/msg/Image``)
    size_bytes: int
    seconds: float  # wall time, building the messages and writing
    start_ns: int  # first log time (ns)
    end_ns: int  # last log time (ns)
    tf_rate_hz: float  # rate of /tf and the sphere markers (0: none)

    def figures(self) -> dict[str, Any]:
        """For the run's summary."""
        return {
            "bytes": self.size_bytes,
            "seconds": round(self.seconds, 3),
            "span_s": round((self.end_ns - self.start_ns) * 1e-9, 3),
            "tf_rate_hz": round(self.tf_rate_hz, 3),
            "topics": self.topics,
        }


@dataclass(frozen=True)
class _Record:
    topic: str
    msgtype: str
    stamp_ns: int  # log time = publish time = header stamp
    data: bytes  # CDR


class _Out:
    """The file's messages, serialized (CDR) as they are made: a message object may then be
    changed and added again (the sphere markers, sample after sample)."""

    def __init__(self, m: MessageBuilder) -> None:
        self.m = m
        self.records: list[_Record] = []

    def add(self, topic: str, msgtype: str, stamp_ns: int, msg: Any) -> None:
        data = bytes(self.m.serialize(msg, msgtype))
        self.records.append(_Record(topic, msgtype, stamp_ns, data))

    def extend(self, messages: Iterable[BagMessage]) -> None:
        for b in messages:
            self.add(b.topic, b.msgtype, b.stamp_ns, b.msg)


def write_run_mcap(
    path: str | Path,
    *,
    start_ns: int,
    frames: Frames | None = None,
    cloud_points: Array | None = None,
    cloud_colors: Array | None = None,
    T_base_cam: Array | None = None,
    robot: RobotModel | None = None,
    spheres: SphereModel | None = None,
    path_q: Array | None = None,
    trajectory: TimedTrajectory | None = None,
    simulated: JointStates | None = None,
    max_rate_hz: float = 100.0,
) -> RunMcap:
    """Write what exists of a run into the MCAP file ``path`` (module doc); None inputs are
    left out (a stage that did not run or failed).

    start_ns: trajectory time 0 (ns). frames: the images used (color (H, W, 3) uint8 RGB,
    depth (H, W) uint16 in ``frames.depth_units``), with intrinsics and stamps.
    cloud_points: (N, 3) m and cloud_colors: (N, 3) RGB in [0, 1], fixed frame. T_base_cam:
    (4, 4) color camera in the fixed frame. robot (and spheres): the model posed for /tf (and
    the sphere markers), needed by path_q and trajectory. path_q: (K, dof) rad, the planned
    path. trajectory: the timed trajectory (t from 0). simulated: the simulated joint states,
    ``t`` (s) from the trajectory's start (their ``start_ns`` is ignored).
    max_rate_hz: highest rate of /tf and the sphere markers.

    Raises ExecutionError naming the file when nothing is given, the inputs disagree (the
    trajectory's joints are not the robot's) or writing fails; nothing is left at ``path``.
    """
    t0 = time.perf_counter()
    target = Path(path)
    if not max_rate_hz > 0:
        raise ExecutionError(f"{target}: max_rate_hz must be > 0, got {max_rate_hz}")
    m = MessageBuilder(2)  # ROS 2 messages, the camera's among them
    out = _Out(m)
    if (path_q is not None or trajectory is not None) and robot is None:
        raise ExecutionError(f"{target}: the path and the trajectory need the robot model")
    fixed = "world" if robot is None else fixed_frame(robot)
    camera_frame = COLOR_FRAME
    try:
        if frames is not None:
            camera_frame = _images(out, frames)
        statics = []
        if T_base_cam is not None:
            statics.append(_transform(m, start_ns, fixed, camera_frame, np.asarray(T_base_cam)))
        if frames is not None:
            statics += _depth_in_color(m, start_ns, frames)
        if statics:
            out.add(TF_STATIC, _TF, start_ns, m.new(_TF, transforms=statics))
        if cloud_points is not None:
            out.add(CLOUD, _CLOUD, start_ns, _cloud(m, start_ns, fixed, cloud_points, cloud_colors))
        if path_q is not None and robot is not None and len(path_q):
            out.add(PATH, _PATH, start_ns, _ee_path(m, start_ns, fixed, robot, path_q))
        tf_rate = 0.0
        if trajectory is not None and robot is not None:
            tf_rate = _trajectory(out, start_ns, fixed, robot, spheres, trajectory, max_rate_hz)
        if simulated is not None:
            sim = replace(
                simulated,
                q=np.ascontiguousarray(simulated.q, dtype=np.float64),  # rows become arrays
                qd=None if simulated.qd is None else np.ascontiguousarray(simulated.qd),
                start_ns=start_ns,
            )
            out.extend(joint_state_messages(sim, m, SIMULATED_STATES))
    except (SerdeError, TypesysError, ValueError, TypeError, KeyError) as err:
        raise ExecutionError(
            f"{target}: cannot make the messages ({type(err).__name__}: {err})"
        ) from err
    if not out.records:
        raise ExecutionError(f"{target}: nothing to write (no stage made anything to show)")
    # In log-time order, stably: each topic keeps its own order.
    records = sorted(out.records, key=lambda r: r.stamp_ns)
    write_file_atomic(target, lambda tmp: _write(tmp, records, m, target), ExecutionError)
    topics: dict[str, int] = {}
    types: dict[str, str] = {}
    for r in out.records:
        topics[r.topic] = topics.get(r.topic, 0) + 1
        types[r.topic] = r.msgtype
    return RunMcap(
        path=target,
        topics=topics,
        types=types,
        size_bytes=target.stat().st_size,
        seconds=time.perf_counter() - t0,
        start_ns=records[0].stamp_ns,
        end_ns=records[-1].stamp_ns,
        tf_rate_hz=tf_rate,
    )


def _write(path: Path, records: Sequence[_Record], m: Messages, target: Path) -> None:
    """The MCAP file at ``path`` (``target``'s temporary name): a schema per type (rosbags'
    ``ros2msg`` text), a channel per topic, the records in their order, zstd chunks."""
    from mcap.exceptions import McapError
    from mcap.writer import CompressionType, Writer

    schemas: dict[str, int] = {}
    channels: dict[str, int] = {}
    counts: dict[str, int] = {}
    try:
        with path.open("wb") as f:
            writer = Writer(f, compression=CompressionType.ZSTD)
            writer.start(profile="ros2", library="gaide run")
            for r in records:
                if r.msgtype not in schemas:
                    text, _ = m.typestore.generate_msgdef(r.msgtype, ros_version=2)
                    schemas[r.msgtype] = writer.register_schema(
                        name=r.msgtype, encoding="ros2msg", data=text.encode()
                    )
                if r.topic not in channels:
                    channels[r.topic] = writer.register_channel(
                        topic=r.topic, message_encoding="cdr", schema_id=schemas[r.msgtype]
                    )
                seq = counts.get(r.topic, 0)
                counts[r.topic] = seq + 1
                writer.add_message(
                    channels[r.topic],
                    log_time=r.stamp_ns,
                    data=r.data,
                    publish_time=r.stamp_ns,
                    sequence=seq,
                )
            writer.finish()
    except (McapError, TypesysError, ValueError, TypeError, KeyError) as err:
        raise ExecutionError(
            f"{target}: writing the MCAP file failed ({type(err).__name__}: {err})"
        ) from err


# -- frames ------------------------------------------------------------------------------


def fixed_frame(robot: RobotModel) -> str:
    """The fixed frame's name: ``world``, unless a link of that name is not at the origin of
    the fixed frame (a placed robot), then ``gaide_world``."""
    if "world" not in robot.links:
        return "world"
    root = robot.link("world")
    if root.parent is None and np.allclose(robot.link_poses(robot.lower)["world"], np.eye(4)):
        return "world"
    return "gaide_world"


def _quats(R: Array) -> Array:
    """(N, 4) quaternions x, y, z, w of rotation matrices (N, 3, 3)."""
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_matrix(R).as_quat(), dtype=np.float64)


def _transform(
    m: Messages, stamp: int, parent: str, child: str, T: Array, quat: Array | None = None
) -> Any:
    """``child``'s pose ``T`` (4, 4) in ``parent`` as a TransformStamped."""
    q = _quats(T[None, :3, :3])[0] if quat is None else quat
    x, y, z = (float(v) for v in T[:3, 3])
    return m.new(
        _TRANSFORM,
        header=m.header(TF, stamp, parent),
        child_frame_id=child,
        transform=m.new(
            "geometry_msgs/msg/Transform",
            translation=m.new("geometry_msgs/msg/Vector3", x=x, y=y, z=z),
            rotation=_quaternion(m, q),
        ),
    )


def _quaternion(m: Messages, q: Array) -> Any:
    x, y, z, w = (float(v) for v in q)
    return m.new("geometry_msgs/msg/Quaternion", x=x, y=y, z=z, w=w)


def _point(m: Messages, p: Array) -> Any:
    x, y, z = (float(v) for v in p)
    return m.new("geometry_msgs/msg/Point", x=x, y=y, z=z)


def _depth_in_color(m: MessageBuilder, stamp: int, frames: Frames) -> list[Any]:
    """The depth camera in the color camera, when both streams and their extrinsics are
    known (without them the depth images have no place in 3D)."""
    if frames.depth is None or frames.color is None or frames.T_color_depth is None:
        return []
    return [_transform(m, stamp, COLOR_FRAME, DEPTH_FRAME, np.asarray(frames.T_color_depth))]


# -- images and cloud --------------------------------------------------------------------


def _images(out: _Out, frames: Frames) -> str:
    """Image and camera_info messages of both streams; returns the frame of the camera
    that ``T_base_cam`` places: the color camera, or the depth camera of a bag without
    color. (The bag's own frame names are not kept: SDK recordings name both "0".)"""
    m = out.m
    if frames.color is not None:
        s = frames.color
        for image, stamp in zip(s.images, s.stamps_ns.tolist(), strict=True):
            msg = m.new(
                _COMPRESSED,
                header=m.header(COLOR_IMAGE, stamp, COLOR_FRAME),
                format="jpeg",
                data=_jpeg(np.asarray(image)),
            )
            out.add(COLOR_IMAGE, _COMPRESSED, stamp, msg)
            info = m.camera_info("", stamp, COLOR_FRAME, s.intrinsics)
            out.add(COLOR_INFO, _INFO, stamp, info)
    if frames.depth is not None:
        s = frames.depth
        for image, stamp in zip(s.images, s.stamps_ns.tolist(), strict=True):
            msg = _depth_image(m, stamp, DEPTH_FRAME, np.asarray(image), frames.depth_units)
            out.add(DEPTH_IMAGE, _IMAGE, stamp, msg)
            info = m.camera_info("", stamp, DEPTH_FRAME, s.intrinsics)
            out.add(DEPTH_INFO, _INFO, stamp, info)
    return COLOR_FRAME if frames.color is not None or frames.depth is None else DEPTH_FRAME


def _jpeg(image: npt.NDArray[Any]) -> npt.NDArray[np.uint8]:
    import cv2

    img = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:
        raise ExecutionError(f"cannot encode a {image.shape} color image as JPEG")
    return np.asarray(buf, dtype=np.uint8).ravel()


def _depth_image(
    m: MessageBuilder, stamp: int, frame: str, image: npt.NDArray[Any], units: float | None
) -> Any:
    """16UC1 (mm, as ROS drivers publish) when the unit is 1 mm or unknown, else 32FC1 (m)."""
    if units is None or math.isclose(units, 1e-3, rel_tol=1e-6):
        return m.image(DEPTH_IMAGE, stamp, frame, image.astype(np.uint16), "16UC1")
    metres = (image.astype(np.float64) * units).astype(np.float32)
    return m.image(DEPTH_IMAGE, stamp, frame, metres, "32FC1")


def _cloud(m: Messages, stamp: int, frame: str, points: Array, colors: Array | None) -> Any:
    """A PointCloud2 of (N, 3) points, with ``rgb`` packed (0x00RRGGBB in a float32, as PCL
    writes it) from (N, 3) colours in [0, 1] when given."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    layout = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if colors is not None:
        layout.append(("rgb", "<u4"))
    arr = np.empty(len(pts), dtype=layout)
    for i, axis in enumerate("xyz"):
        arr[axis] = pts[:, i]
    if colors is not None:
        c = np.clip(np.rint(np.asarray(colors, dtype=np.float64) * 255), 0, 255).astype(np.uint32)
        arr["rgb"] = (c[:, 0] << 16) | (c[:, 1] << 8) | c[:, 2]
    float32 = 7  # sensor_msgs/PointField.FLOAT32
    fields = [
        m.new(_FIELD, name=name, offset=4 * i, datatype=float32, count=1)
        for i, (name, _) in enumerate(layout)
    ]
    step = arr.dtype.itemsize
    return m.new(
        _CLOUD,
        header=m.header(CLOUD, stamp, frame),
        height=1,
        width=len(pts),
        fields=fields,
        is_bigendian=False,
        point_step=step,
        row_step=step * len(pts),
        data=np.frombuffer(arr.tobytes(), dtype=np.uint8),
        is_dense=True,
    )


# -- the robot ---------------------------------------------------------------------------


def sample_indices(n: int, rate_hz: float, max_rate_hz: float) -> IntArray:
    """Indices of ``n`` samples at ``rate_hz`` kept for at most ``max_rate_hz``: every k-th
    from the first, and the last."""
    step = max(1, math.ceil(rate_hz / max_rate_hz - 1e-9))
    idx = np.arange(0, n, step, dtype=np.int64)
    if n and idx[-1] != n - 1:
        idx = np.append(idx, n - 1)
    return idx


def _link_poses(robot: RobotModel, Q: Array) -> tuple[list[str], Array]:
    """Link names and their poses (B, L, 4, 4) in the fixed frame at configurations Q."""
    names = list(robot.links)
    poses = np.empty((len(Q), len(names), 4, 4))
    for i, q in enumerate(Q):
        by_name = robot.link_poses(q)
        poses[i] = [by_name[n] for n in names]
    return names, poses


def _robot_order(robot: RobotModel, traj: TimedTrajectory) -> list[int]:
    missing = [n for n in robot.joint_names if n not in traj.joint_names]
    if missing:
        raise ExecutionError(
            f"the trajectory lacks the robot's joints {missing} (it has {list(traj.joint_names)})"
        )
    return [traj.joint_names.index(n) for n in robot.joint_names]


def _trajectory(
    out: _Out,
    start_ns: int,
    fixed: str,
    robot: RobotModel,
    spheres: SphereModel | None,
    traj: TimedTrajectory,
    max_rate_hz: float,
) -> float:
    """/joint_trajectory, /joint_states_planned, and /tf with the sphere markers at the
    kept samples; returns the rate of /tf (Hz)."""
    m = out.m
    order = _robot_order(robot, traj)
    states = JointStates(
        names=traj.joint_names,
        t=traj.t,
        q=np.ascontiguousarray(traj.q, dtype=np.float64),  # rows become message arrays
        qd=np.ascontiguousarray(traj.qd, dtype=np.float64),
        start_ns=start_ns,
        error=ExecutionError,
    )
    stamps = states.stamps_ns
    out.add(TRAJECTORY, _TRAJECTORY, start_ns, _joint_trajectory(m, start_ns, traj))
    out.extend(joint_state_messages(states, m, PLANNED_STATES))
    idx = sample_indices(len(traj.t), traj.rate_hz, max_rate_hz)
    names, poses = _link_poses(robot, traj.q[idx][:, order])
    parents = [robot.links[n].parent for n in names]
    # Each link in its parent link (a tree Foxglove's URDF layer resolves); a root link in
    # the fixed frame unless it is the fixed frame itself.
    rel = np.empty_like(poses)
    for j, parent in enumerate(parents):
        rel[:, j] = (
            poses[:, j]
            if parent is None
            else np.linalg.inv(poses[:, names.index(parent)]) @ poses[:, j]
        )
    keep = [j for j, n in enumerate(names) if not (parents[j] is None and n == fixed)]
    quats = _quats(rel[:, keep, :3, :3].reshape(-1, 3, 3)).reshape(len(idx), len(keep), 4)
    markers = _SphereMarkers(m, robot, spheres, names, fixed) if spheres is not None else None
    for i, stamp in enumerate(stamps[idx].tolist()):
        tfs = [
            _transform(m, stamp, parents[j] or fixed, names[j], rel[i, j], quats[i, k])
            for k, j in enumerate(keep)
        ]
        out.add(TF, _TF, stamp, m.new(_TF, transforms=tfs))
        if markers is not None:
            out.add(SPHERES, _MARKERS, stamp, markers.at(stamp, poses[i]))
    if len(idx) < 2:
        return 0.0
    return float((len(idx) - 1) / (traj.t[idx[-1]] - traj.t[idx[0]]))


def _joint_trajectory(m: Messages, stamp: int, traj: TimedTrajectory) -> Any:
    empty = np.zeros(0, dtype=np.float64)
    points = [
        m.new(
            _POINT,
            positions=np.ascontiguousarray(traj.q[i], dtype=np.float64),
            velocities=np.ascontiguousarray(traj.qd[i], dtype=np.float64),
            accelerations=np.ascontiguousarray(traj.qdd[i], dtype=np.float64),
            effort=empty,
            time_from_start=m.duration(float(traj.t[i])),
        )
        for i in range(len(traj.t))
    ]
    return m.new(
        _TRAJECTORY,
        header=m.header(TRAJECTORY, stamp),
        joint_names=list(traj.joint_names),
        points=points,
    )


class _SphereMarkers:
    """The collision spheres as SPHERE markers in the fixed frame (one per sphere, id = its
    index in the sphere model, namespace = its link). One MarkerArray is made once; each
    sample moves its spheres and restamps it (:class:`_Out` serializes it at once): a third
    of the time that making every marker anew at every sample takes."""

    def __init__(
        self, m: Messages, robot: RobotModel, spheres: SphereModel, names: list[str], fixed: str
    ) -> None:
        spheres.check_against(robot)
        self.m, self.spheres = m, spheres
        self.link_index = np.array([names.index(n) for n in spheres.links], dtype=np.int64)
        colors = {n: PALETTE[i % len(PALETTE)] for i, n in enumerate(spheres.link_names)}
        identity = _quaternion(m, np.array([0.0, 0.0, 0.0, 1.0]))
        nothing = np.zeros(0, dtype=np.uint8)
        self.header = m.header(SPHERES, 0, fixed)  # shared by the markers
        self.points = [_point(m, np.zeros(3)) for _ in spheres.links]
        markers = [
            m.new(
                _MARKER,
                header=self.header,
                ns=link,
                id=s,
                type=2,  # SPHERE
                action=0,  # ADD (replaces the marker of the same ns and id)
                pose=m.new("geometry_msgs/msg/Pose", position=point, orientation=identity),
                scale=m.new("geometry_msgs/msg/Vector3", x=2 * r, y=2 * r, z=2 * r),
                color=m.new(
                    "std_msgs/msg/ColorRGBA",
                    **dict(zip("rgb", colors[link], strict=True)),
                    a=SPHERE_ALPHA,
                ),
                lifetime=m.duration(0.0),  # forever (until the next sample replaces it)
                frame_locked=False,
                points=[],
                colors=[],
                texture_resource="",
                texture=m.new(_COMPRESSED, header=m.header("", 0), format="", data=nothing),
                uv_coordinates=[],
                text="",
                mesh_resource="",
                mesh_file=m.new("visualization_msgs/msg/MeshFile", filename="", data=nothing),
                mesh_use_embedded_materials=False,
            )
            for s, (link, r, point) in enumerate(
                zip(spheres.links, spheres.radii.tolist(), self.points, strict=True)
            )
        ]
        self.array = m.new(_MARKERS, markers=markers)

    def at(self, stamp: int, poses: Array) -> Any:
        """The markers at the link poses (L, 4, 4) of one sample, stamped ``stamp`` (ns):
        valid until the next call."""
        P = poses[self.link_index]  # (S, 4, 4)
        centres = np.einsum("sij,sj->si", P[:, :3, :3], self.spheres.centers) + P[:, :3, 3]
        self.header.stamp = self.m.time(stamp)
        for point, (x, y, z) in zip(self.points, centres.tolist(), strict=True):
            point.x, point.y, point.z = x, y, z
        return self.array


def _ee_path(m: Messages, stamp: int, fixed: str, robot: RobotModel, path_q: Array) -> Any:
    """The end effector's poses along the path's straight joint-space edges, at most
    :data:`PATH_STEP_RAD` apart (joint space)."""
    from planning.path_ops import resample

    Q = resample(np.asarray(path_q, dtype=np.float64), PATH_STEP_RAD)
    T = np.array([robot.frame_pose(q) for q in Q])
    quats = _quats(T[:, :3, :3])
    header = m.header(PATH, stamp, fixed)
    poses = [
        m.new(
            "geometry_msgs/msg/PoseStamped",
            header=header,
            pose=m.new(
                "geometry_msgs/msg/Pose",
                position=_point(m, T[i, :3, 3]),
                orientation=_quaternion(m, quats[i]),
            ),
        )
        for i in range(len(Q))
    ]
    return m.new(_PATH, header=header, poses=poses)
