"""The scene as a point cloud in the robot's base frame, from one recording.

Steps: fuse depth over frames (median), deproject, colour through the depth-to-color
extrinsics (optional), move to the base frame with ``T_base_cam`` (the *color* camera's
pose, as calibration measures it), crop to the workspace box, remove the robot's own points
(spheres given by the caller, in the base frame), voxel-downsample and drop outliers (Open3D).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import open3d as o3d

from gaide_core.camera import Intrinsics
from gaide_core.errors import PerceptionError
from gaide_core.native_output import quiet_native_output
from gaide_core.transforms import apply, is_rigid
from gaide_core.types import Array
from perception.cloud_cfg import CloudCfg
from perception.depth import deprojector_for, fuse_depth, project
from perception.frames import Frames

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SceneCloud:
    """A cloud in the base frame, with what each step kept."""

    points: Array  # (N, 3) m, base frame
    colors: Array | None  # (N, 3) RGB in [0, 1], or None
    counts: dict[str, int] = field(default_factory=dict)  # points after each step
    seconds: float = 0.0

    def __len__(self) -> int:
        return len(self.points)


def remove_inside_spheres(
    points: Array, centers: Array, radii: Array, chunk: int = 65_536
) -> npt.NDArray[np.bool_]:
    """(N,) True for points outside every sphere (centres (S, 3), radii (S,), same frame).
    Only points inside the spheres' bounding box are tested one by one."""
    keep = np.ones(len(points), bool)
    lo, hi = (centers - radii[:, None]).min(axis=0), (centers + radii[:, None]).max(axis=0)
    near = np.flatnonzero(np.all((points >= lo) & (points <= hi), axis=1))
    r2 = radii**2
    for s in range(0, len(near), chunk):
        idx = near[s : s + chunk]
        d2 = np.sum((points[idx, None, :] - centers[None]) ** 2, axis=-1)
        keep[idx] = np.all(d2 > r2[None], axis=1)
    return keep


def _same_camera(a: Intrinsics, b: Intrinsics) -> bool:
    """Whether two streams share their pixels (depth aligned to color): then the identity
    relates them. (Intrinsics hold arrays, so ``==`` on them is no truth value.)"""
    return (a.width, a.height) == (b.width, b.height) and np.array_equal(a.K, b.K)


def scene_cloud(
    frames: Frames,
    T_base_cam: Array,
    cfg: CloudCfg | None = None,
    *,
    robot_spheres: tuple[Array, Array] | None = None,
    colored: bool = True,
) -> SceneCloud:
    """The recording's scene in the base frame.

    T_base_cam: (4, 4) pose of the color camera in the base frame (from calibration).
    robot_spheres: (centres (S, 3) in the base frame, radii (S,)) of the robot at the
    recorded joint state; points inside them (plus ``cfg.robot_padding``) are removed.
    """
    cfg = cfg or CloudCfg()
    t0 = time.perf_counter()
    if not is_rigid(np.asarray(T_base_cam, float)):
        raise PerceptionError("T_base_cam must be a 4x4 rigid transform")
    if frames.depth is None or len(frames.depth) == 0:
        raise PerceptionError(f"{frames.source}: no depth frames to build a cloud from")
    if frames.depth_units is None:
        raise PerceptionError(f"{frames.source}: depth units unknown; pass them explicitly")
    T_color_depth = frames.T_color_depth
    if T_color_depth is None:
        if frames.color is not None and not _same_camera(
            frames.color.intrinsics, frames.depth.intrinsics
        ):
            raise PerceptionError(
                f"{frames.source}: depth-to-color extrinsics are missing, needed to place depth "
                "points in the calibrated color frame; to assume the identity, opt in with "
                "--default-extrinsics (gaide perceive), perception.default_extrinsics: true "
                "(gaide run) or read_bag(..., default_extrinsics=True)"
            )
        T_color_depth = np.eye(4)
    depth_m = fuse_depth(frames.depth.images[: cfg.max_frames], frames.depth_units)
    pts_depth, _ = deprojector_for(frames.depth.intrinsics).points(
        depth_m, cfg.min_depth, cfg.max_depth
    )
    counts = {"deprojected": len(pts_depth)}
    if len(pts_depth) == 0:
        raise PerceptionError(
            f"{frames.source}: no depth pixel between {cfg.min_depth} and {cfg.max_depth} m"
        )
    colors = None
    if colored and frames.color is not None and len(frames.color):
        colors = _sample_colors(apply(T_color_depth, pts_depth), frames.color.images[0], frames)
    pts = apply(np.asarray(T_base_cam, float) @ T_color_depth, pts_depth)
    lo, hi = np.asarray(cfg.workspace_min), np.asarray(cfg.workspace_max)
    inside = np.all((pts >= lo) & (pts <= hi), axis=1)
    pts, colors = pts[inside], None if colors is None else colors[inside]
    counts["in_workspace"] = len(pts)
    if len(pts) == 0:
        raise PerceptionError(
            f"{frames.source}: no points left inside the workspace box {cfg.workspace_min} .. "
            f"{cfg.workspace_max} (base frame): check T_base_cam and the box"
        )
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    if colors is not None:
        pcd.colors = o3d.utility.Vector3dVector(colors)
    if cfg.voxel > 0:
        pcd = pcd.voxel_down_sample(cfg.voxel)
    counts["downsampled"] = len(pcd.points)
    if robot_spheres is not None:
        # After downsampling: the same spheres, an eighth of the points to test.
        centers, radii = robot_spheres
        keep = remove_inside_spheres(
            np.asarray(pcd.points),
            np.asarray(centers, float),
            np.asarray(radii, float) + cfg.robot_padding,
        )
        pcd = pcd.select_by_index(np.flatnonzero(keep).tolist())
        counts["robot_removed"] = int(np.sum(~keep))
    if len(pcd.points) == 0:
        raise PerceptionError(
            f"{frames.source}: nothing left once the robot's own points are removed"
        )
    if cfg.outlier_neighbors > 0 and len(pcd.points) > cfg.outlier_neighbors:
        pcd, _ = pcd.remove_statistical_outlier(cfg.outlier_neighbors, cfg.outlier_std)
    counts["final"] = len(pcd.points)
    out_colors = np.asarray(pcd.colors) if colors is not None else None
    return SceneCloud(np.asarray(pcd.points), out_colors, counts, time.perf_counter() - t0)


def _sample_colors(pts_color: Array, image: np.ndarray, frames: Frames) -> Array:
    """RGB in [0, 1] for points in the color frame; grey where outside the color image."""
    assert frames.color is not None
    uv, inside = project(pts_color, frames.color.intrinsics)
    colors = np.full((len(pts_color), 3), 0.5)
    col = np.clip(np.rint(uv[inside]).astype(np.int64), 0, None)
    h, w = image.shape[:2]
    colors[inside] = image[np.minimum(col[:, 1], h - 1), np.minimum(col[:, 0], w - 1)] / 255.0
    return colors


def save_ply(path: str, cloud: SceneCloud) -> None:
    """Write the cloud as PLY atomically (temporary file, then rename), read back and
    counted first: Open3D reports success for a file a full disk cut short."""
    from pathlib import Path

    target = Path(path)
    tmp = target.with_name(f".{target.stem}.tmp.ply")
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(cloud.points))
    if cloud.colors is not None:
        pcd.colors = o3d.utility.Vector3dVector(cloud.colors)
    try:
        with quiet_native_output():  # RPly prints a line per vertex it fails to write
            written = o3d.io.write_point_cloud(tmp, pcd)
        if not written:
            raise PerceptionError(f"cannot write {target} (is the disk full?)")
        try:
            check_ply_complete(tmp)
        except PerceptionError as err:
            raise PerceptionError(
                f"cannot write {target}: it reads back incomplete (is the disk full?)"
            ) from err
        with quiet_native_output():
            back = len(o3d.io.read_point_cloud(tmp).points)
        if back != len(cloud.points):
            raise PerceptionError(f"cannot write {target}: the file reads back short")
        tmp.replace(target)
    except OSError as err:
        raise PerceptionError(f"cannot write {target}: {err.strerror or err}") from err
    finally:
        tmp.unlink(missing_ok=True)


def load_ply(path: str) -> Array:
    """Points (N, 3) of a PLY file; PerceptionError if missing, unreadable, cut short or
    empty, or if a point is not finite."""
    from pathlib import Path

    source = Path(path)
    if not source.is_file():
        raise PerceptionError(f"cloud file {source} does not exist")
    check_ply_complete(source)
    pcd = o3d.io.read_point_cloud(source)
    pts = np.asarray(pcd.points)
    if len(pts) == 0:
        raise PerceptionError(f"cloud file {source} holds no points (or is not a point cloud)")
    if not np.isfinite(pts).all():
        raise PerceptionError(f"cloud file {source} has points that are not finite numbers")
    return pts


_PLY_SIZES = {
    "char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2,
    "uint16": 2, "int": 4, "uint": 4, "float": 4, "int32": 4, "uint32": 4, "float32": 4,
    "double": 8, "float64": 8,
}  # fmt: skip


def check_ply_complete(path: object) -> None:
    """PerceptionError unless the PLY file at ``path`` holds as many vertices as its header
    announces. Open3D reads a file cut short without a word, the missing points as (0, 0, 0);
    this reads the header (written by hand: it is a few lines of text, and no well-kept
    library checks it) and compares with the file's size (binary) or lines (ASCII)."""
    from pathlib import Path

    p = Path(str(path))
    try:
        with p.open("rb") as f:
            head = f.read(65536)
        size = p.stat().st_size
    except OSError as err:
        raise PerceptionError(f"cloud file {p} cannot be read: {err.strerror or err}") from err
    end = head.find(b"end_header\n")
    if not head.startswith(b"ply") or end < 0:
        raise PerceptionError(f"cloud file {p} is not a PLY file (no PLY header)")
    lines = head[:end].decode("ascii", "replace").splitlines()
    fmt = next((ln.split()[1] for ln in lines if ln.startswith("format ")), "")
    elements: list[tuple[str, int, list[str]]] = []
    for ln in lines:
        words = ln.split()
        if words[:1] == ["element"] and len(words) == 3:
            elements.append((words[1], int(words[2]), []))
        elif words[:1] == ["property"] and elements:
            elements[-1][2].append(" ".join(words[1:]))
    vertex = next((e for e in elements if e[0] == "vertex"), None)
    if vertex is None or any(prop.startswith("list") for e in elements for prop in e[2]):
        return  # a mesh's variable-length lists: nothing to compare with
    body = size - (end + len(b"end_header\n"))
    if fmt.startswith("binary"):
        need = sum(n * sum(_PLY_SIZES.get(prop.split()[0], 0) for prop in props)
                   for _, n, props in elements)  # fmt: skip
        if body < need:
            raise PerceptionError(
                f"cloud file {p} is cut short: its header announces {vertex[1]:,} points, the "
                f"file holds {body:,} of the {need:,} bytes they need"
            )
    elif fmt == "ascii":
        with p.open("rb") as f:
            f.seek(end + len(b"end_header\n"))
            rows = sum(1 for line in f if line.strip())
        if rows < sum(n for _, n, _ in elements):
            raise PerceptionError(
                f"cloud file {p} is cut short: its header announces {vertex[1]:,} points, it "
                f"holds {rows:,} rows"
            )
