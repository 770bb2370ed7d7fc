"""The run in 3D for ``report.html``: an interactive plotly view (WebGL) of the scene cloud,
the camera's frustum, the robot's collision spheres moving along the timed trajectory (a
time slider and a play button), the end effector's trace and the closest approach to the
scene.

Everything is in the robot's base frame (m). :func:`scene_html` draws a :class:`Scene3D`
(plain arrays) as an HTML fragment with plotly.js inline, so the page works offline;
:func:`motion_scene` computes one from a collision checker and joint samples, and
:func:`run_scene` from a run's output folder.

Each collision sphere is drawn as a 42-vertex icosphere with its vertices on the sphere:
its faces lie inside it, at least 0.93 radius from the centre (plotly's markers are sized
in screen pixels, so they cannot show a radius in metres). The page holds at most
:data:`MAX_FRAMES` robot poses and :data:`MAX_POINTS` cloud points, as float32.
"""

from __future__ import annotations

import base64
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from gaide_core.types import Array

if TYPE_CHECKING:
    from gaide.pipeline.config import RunCfg
    from planning.collision import CollisionChecker

MAX_POINTS = 30_000  # cloud points drawn at most (an even subset)
MAX_FRAMES = 50  # robot poses in the animation at most (each adds ~23 kB to the page)
MAX_CLEARANCE_SAMPLES = 5_000  # trajectory samples searched for the closest approach
TRACE_SAMPLES = 300  # end-effector positions in its trace at most
FRUSTUM_DEPTH = 0.3  # m, how far the drawn camera pyramid reaches
DIV_ID = "scene3d"  # the plot's element id in the page


@dataclass(frozen=True, kw_only=True)
class CameraView:
    """The camera in the base frame: ``T_base_cam`` (4, 4), optical frame (z forward).
    ``K`` (3, 3) px for ``width`` x ``height`` images, or None: the pose alone is known."""

    T_base_cam: Array
    K: Array | None = None
    width: int = 0  # px
    height: int = 0  # px


@dataclass(frozen=True, kw_only=True)
class Closest:
    """The smallest sphere-to-scene clearance along the motion."""

    sample: int  # index into the motion's samples
    t: float | None  # s; None along an untimed path
    clearance: float  # m, true: to the nearest cloud point (or primitive), minus the radius
    centres: Array  # (S, 3) m, every sphere's centre at that sample
    sphere: int  # the closest sphere
    radius: float  # m, its radius
    obstacle: Array  # (3,) m, the cloud point nearest to it


@dataclass(frozen=True, kw_only=True)
class Scene3D:
    """What the view draws, in the base frame (m)."""

    points: Array  # (N, 3) the scene cloud
    colors: Array | None  # (N, 3) RGB in [0, 1]; None: shaded by height
    camera: CameraView | None = None
    radii: Array  # (S,) the collision spheres' radii
    centres: Array  # (F, S, 3) sphere centres at each animation frame (F = 0: no robot)
    times: Array | None  # (F,) s of each frame; None: frames evenly along an untimed path
    trace: Array  # (M, 3) the end effector's positions along the motion
    closest: Closest | None = None

    def __post_init__(self) -> None:
        n, f = len(self.points), len(self.centres)
        if self.points.ndim != 2 or self.points.shape[1] != 3 or n == 0:
            raise ValueError(f"points must be (N, 3), N > 0; got {self.points.shape}")
        if self.colors is not None and self.colors.shape != (n, 3):
            raise ValueError(f"colors must be ({n}, 3); got {self.colors.shape}")
        if f and self.centres.shape[1:] != (len(self.radii), 3):
            raise ValueError(f"centres must be (F, {len(self.radii)}, 3); got {self.centres.shape}")
        if self.times is not None and len(self.times) != f:
            raise ValueError(f"times must hold one time per frame ({f}); got {len(self.times)}")


# -- from a motion -----------------------------------------------------------------------


def motion_scene(
    checker: CollisionChecker,
    Q: Array,
    times: Array | None,
    points: Array,
    colors: Array | None,
    camera: CameraView | None,
    *,
    frames: int = MAX_FRAMES,
) -> Scene3D:
    """The scene of the robot moving through ``Q`` (K, dof) rad, sampled at ``times`` (K,)
    s (None: an untimed path), in the cloud ``points`` (N, 3) m that ``checker``'s world
    was built from. The closest approach is searched over (at most
    :data:`MAX_CLEARANCE_SAMPLES` evenly spaced) samples (:func:`closest_approach`)."""
    Q = np.asarray(Q, float)
    k = len(Q)
    frame_idx = np.unique(np.round(np.linspace(0, k - 1, min(frames, k))).astype(int))
    trace_idx = np.unique(np.round(np.linspace(0, k - 1, min(TRACE_SAMPLES, k))).astype(int))
    robot = checker.robot
    return Scene3D(
        points=points,
        colors=colors,
        camera=camera,
        radii=np.asarray(checker.radii, float),
        centres=checker.sphere_centers(Q[frame_idx]),
        times=None if times is None else np.asarray(times, float)[frame_idx],
        trace=np.array([robot.frame_pose(q)[:3, 3] for q in Q[trace_idx]]),
        closest=closest_approach(checker, Q, times, points),
    )


def closest_approach(
    checker: CollisionChecker, Q: Array, times: Array | None, points: Array
) -> Closest | None:
    """The sample of ``Q`` (K, dof) with the smallest true world clearance
    (:func:`planning.checker.true_sphere_clearance`: on a cloud the distance to its nearest
    point, not the checker's lattice look-up, which is a lower bound), its closest sphere and
    the cloud point (of ``points`` (N, 3), the world's) nearest to that sphere; None when the
    world is empty."""
    from scipy.spatial import cKDTree

    from planning.checker import true_sphere_clearance

    stride = max(1, -(-len(Q) // MAX_CLEARANCE_SAMPLES))
    idx = np.arange(0, len(Q), stride)
    clearance = true_sphere_clearance(checker, Q[idx])  # (B, S), +inf: not world-checked
    best, sphere = np.unravel_index(int(np.argmin(clearance)), clearance.shape)
    value = float(clearance[best, sphere])
    if not np.isfinite(value):
        return None
    sample = int(idx[best])
    centres = checker.sphere_centers(Q[sample : sample + 1])[0]
    _, nearest = cKDTree(points).query(centres[sphere])
    return Closest(
        sample=sample,
        t=None if times is None else float(times[sample]),
        clearance=value,
        centres=centres,
        sphere=int(sphere),
        radius=float(np.asarray(checker.radii, float)[sphere]),
        obstacle=np.asarray(points[int(nearest)], float),
    )


# -- from a run's output folder ----------------------------------------------------------


def run_scene(out: Path, cfg: RunCfg, checker: CollisionChecker | None = None) -> Scene3D:
    """The scene of the run in ``out`` (its files: ``scene.ply``, ``calibration.yaml``,
    ``trajectory.csv``/``.json`` or else ``plan.json``), with the settings ``cfg`` it ran
    with. ``checker``: the planning stage's, if at hand; else built again from the cloud
    and the settings (the same world, so the same answers). FileNotFoundError when the run
    wrote no cloud."""
    points, colors = _read_cloud(out / "scene.ply")
    camera = _camera(out, cfg)
    motion = _motion(out)
    if motion is None:
        return Scene3D(
            points=points,
            colors=colors,
            camera=camera,
            radii=np.zeros(0),
            centres=np.zeros((0, 0, 3)),
            times=None,
            trace=np.zeros((0, 3)),
        )
    if checker is None:
        from planning.checker import make_checker
        from planning.distance_field import CloudWorld
        from planning.robot_setup import robot_and_spheres

        robot, spheres = robot_and_spheres(cfg.robot)
        world = CloudWorld(points, voxel=cfg.planning.world_voxel)
        checker = make_checker(robot, spheres, world, backend=cfg.planning.checker)
    Q, times = motion
    return motion_scene(checker, Q, times, points, colors, camera)


def _read_cloud(path: Path) -> tuple[Array, Array | None]:
    if not path.is_file():  # before Open3D loads: a run that failed early reports at once
        raise FileNotFoundError(f"no scene cloud ({path.name}): the perception stage wrote none")
    import open3d as o3d

    pcd = o3d.io.read_point_cloud(path)
    points = np.asarray(pcd.points, float)
    colors = np.asarray(pcd.colors, float) if pcd.has_colors() else None
    return points, colors


def _camera(out: Path, cfg: RunCfg) -> CameraView | None:
    from calibration.result import load_calibration
    from gaide_core.transforms import from_xyz_quat

    if (out / "calibration.yaml").is_file():
        c = load_calibration(out / "calibration.yaml")
        return CameraView(T_base_cam=c.T_base_cam, K=c.K, width=c.width, height=c.height)
    pose = cfg.calibration.T_base_cam
    if pose is None:
        return None
    quat = np.asarray(pose[3:], float)
    return CameraView(T_base_cam=from_xyz_quat(pose[:3], quat / np.linalg.norm(quat)))


def _motion(out: Path) -> tuple[Array, Array | None] | None:
    """Joint samples (K, dof) rad and their times (K,) s: the timed trajectory's, else the
    planned path's (no times); None when the run got no path."""
    from execution.trajectory_io import read_trajectory
    from gaide.pipeline.figures import poses_along
    from gaide_core.plan_file import read_plan

    for name in ("trajectory.csv", "trajectory.json"):
        if (out / name).is_file():
            traj = read_trajectory(out / name)
            return traj.q, traj.t
    if (out / "plan.json").is_file():
        return poses_along(read_plan(out / "plan.json").path, MAX_FRAMES * 4), None
    return None


# -- the figure --------------------------------------------------------------------------


def _icosphere() -> tuple[Array, npt.NDArray[np.int64]]:
    """A unit icosphere: vertices (42, 3) and triangles (80, 3), one subdivision of the
    icosahedron."""
    g = (1 + 5**0.5) / 2
    v = [
        [-1, g, 0], [1, g, 0], [-1, -g, 0], [1, -g, 0], [0, -1, g], [0, 1, g],
        [0, -1, -g], [0, 1, -g], [g, 0, -1], [g, 0, 1], [-g, 0, -1], [-g, 0, 1],
    ]  # fmt: skip
    faces = [
        (0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
        (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
        (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1),
    ]  # fmt: skip
    verts = [np.asarray(p, float) / np.linalg.norm(p) for p in v]
    middle: dict[tuple[int, int], int] = {}

    def mid(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in middle:
            p = verts[a] + verts[b]
            verts.append(p / np.linalg.norm(p))
            middle[key] = len(verts) - 1
        return middle[key]

    split = []
    for a, b, c in faces:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        split += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    return np.array(verts), np.array(split, np.int64)


_UNIT, _TRIANGLES = _icosphere()


def spheres_mesh(centres: Array, radii: Array) -> Array:
    """Vertices (S * 42, 3) of one icosphere per sphere (centres (S, 3), radii (S,) m);
    their triangles are :func:`spheres_triangles`."""
    return (centres[:, None, :] + radii[:, None, None] * _UNIT[None]).reshape(-1, 3)


def spheres_triangles(count: int) -> npt.NDArray[np.int64]:
    """Triangles (count * 80, 3) of :func:`spheres_mesh`'s vertices."""
    offsets = np.arange(count)[:, None, None] * len(_UNIT)
    return (_TRIANGLES[None] + offsets).reshape(-1, 3)


def frustum(camera: CameraView, depth: float = FRUSTUM_DEPTH) -> Array:
    """Polyline (with NaN breaks) of the camera's viewing pyramid, ``depth`` m deep, in the
    base frame: apex to the image corners, then the image rectangle."""
    assert camera.K is not None
    w, h = camera.width, camera.height
    pixels = np.array([[0, 0, 1], [w, 0, 1], [w, h, 1], [0, h, 1]], float)
    rays = pixels @ np.linalg.inv(camera.K).T  # z = 1 in the optical frame
    corners = rays * depth
    apex = np.zeros(3)
    gap = np.full(3, np.nan)
    seq = [apex, corners[0], gap, apex, corners[1], gap, apex, corners[2], gap, apex]
    seq += [corners[3], corners[0], corners[1], corners[2], corners[3]]
    local = np.array(seq)
    T = camera.T_base_cam
    return local @ T[:3, :3].T + T[:3, 3]


def _subset(points: Array, colors: Array | None) -> tuple[Array, list[str]]:
    """At most :data:`MAX_POINTS` points (an even subset) and their colours as ``#rrggbb``."""
    step = max(1, -(-len(points) // MAX_POINTS))
    pts = points[::step]
    if colors is not None:
        rgb = np.clip(colors[::step], 0.0, 1.0)
    else:
        z = pts[:, 2]
        shade = 0.35 + 0.45 * (z - z.min()) / max(float(np.ptp(z)), 1e-9)
        rgb = np.stack([shade] * 3, axis=1)
    levels = np.round(rgb * 255).astype(int)
    return pts, [f"#{r:02x}{g:02x}{b:02x}" for r, g, b in levels]


_DTYPES = {np.dtype(np.float32): "f4", np.dtype(np.uint16): "u2", np.dtype(np.int32): "i4"}


def _typed(a: npt.ArrayLike, dtype: npt.DTypeLike = np.float32) -> dict[str, str]:
    """A plotly.js typed array (``{dtype, bdata}``: little-endian, base64): 4 bytes a
    float32 in the page, where a JSON number takes about 20."""
    arr = np.ascontiguousarray(a, np.dtype(dtype).newbyteorder("<"))
    code = _DTYPES[np.dtype(dtype)]
    return {"dtype": code, "bdata": base64.b64encode(arr.tobytes()).decode()}


def _xyz(points: Array) -> dict[str, Any]:
    return {k: _typed(points[:, n]) for n, k in enumerate("xyz")}


def _mesh(vertices: Array, count: int, **style: Any) -> dict[str, Any]:
    """One mesh of ``count`` icospheres (:func:`spheres_mesh`'s ``vertices``)."""
    tri = spheres_triangles(count)
    index = np.uint16 if tri.size and tri.max() < 2**16 else np.int32
    faces = {k: _typed(tri[:, n], index) for n, k in enumerate("ijk")}
    return {"type": "mesh3d", **_xyz(vertices), **faces, "hoverinfo": "skip", **style}


def _lines(xyz: Array, name: str, color: str, **style: Any) -> dict[str, Any]:
    line = {"color": color, "width": 4}
    return {"type": "scatter3d", "mode": "lines", **_xyz(xyz), "name": name, "line": line, **style}


def _mm(m: float) -> str:
    return f"{m * 1000:.1f} mm"


def _label(scene: Scene3D, index: int) -> str:
    if scene.times is not None:
        return f"{scene.times[index]:.2f}"
    return f"{100 * index / max(len(scene.centres) - 1, 1):.0f}"


def scene_figure(scene: Scene3D) -> dict[str, Any]:
    """The plotly figure of ``scene`` as plotly.js reads it (``data``, ``layout``,
    ``frames``). Plain dicts: plotly.py's figure objects check every value one by one,
    seconds for a cloud's colours."""
    pts, hex_colors = _subset(scene.points, scene.colors)
    cloud = {
        "type": "scatter3d",
        "mode": "markers",
        **_xyz(pts),
        "name": f"scene cloud ({len(pts):,} of {len(scene.points):,} points)",
        "marker": {"size": 2, "color": hex_colors},
        "hoverinfo": "skip",
    }
    data: list[dict[str, Any]] = [cloud]
    for axis, color in zip(np.eye(3) * 0.2, ("red", "green", "blue"), strict=True):
        data.append(_lines(np.stack([np.zeros(3), axis]), "base frame", color, showlegend=False))
    extent = [scene.points]
    if scene.camera is not None:
        cam = scene.camera
        if cam.K is not None:
            drawn = frustum(cam)
            data.append(_lines(drawn, f"camera ({cam.width}x{cam.height} px)", "#444"))
        else:  # the pose alone: its optical axis
            drawn = cam.T_base_cam[:3, 3] + np.outer([0, FRUSTUM_DEPTH], cam.T_base_cam[:3, 2])
            data.append(_lines(drawn, "camera (optical axis)", "#444"))
        extent.append(drawn[np.isfinite(drawn).all(axis=1)])
    count = len(scene.radii)
    figure: dict[str, Any] = {"data": data}
    if len(scene.centres):
        reach = scene.radii[None, :, None]
        extent += [scene.centres - reach, scene.centres + reach]
        data.append(_lines(scene.trace, "end effector", "black"))
        for centres, name, color in (
            (scene.centres[0], "start", "royalblue"),
            (scene.centres[-1], "goal", "crimson"),
        ):
            mesh = spheres_mesh(centres, scene.radii)
            data.append(_mesh(mesh, count, name=name, color=color, opacity=0.2, showlegend=True))
        if scene.closest is not None:
            data += _closest(scene, count)
        robot = len(data)
        mesh = spheres_mesh(scene.centres[0], scene.radii)
        data.append(
            _mesh(mesh, count, name="robot (collision spheres)", color="#f0a020", showlegend=True)
        )
        figure["frames"] = [
            {"name": str(k), "data": [_xyz(spheres_mesh(c, scene.radii))], "traces": [robot]}
            for k, c in enumerate(scene.centres)
        ]
    lo, hi = _bounds(extent)
    figure["layout"] = {
        "height": 720,
        "margin": {"l": 0, "r": 0, "t": 30, "b": 0},
        "legend": {"x": 0.01, "y": 0.99, "bgcolor": "rgba(255,255,255,0.7)"},
        "scene": _scene_layout(lo, hi, scene.camera),
        "uirevision": "keep",
        **(_controls(scene) if len(scene.centres) else {}),
    }
    return figure


def _closest(scene: Scene3D, count: int) -> list[dict[str, Any]]:
    """The robot at the closest approach, and a segment from its closest sphere to the
    nearest cloud point, labelled with the clearance."""
    c = scene.closest
    assert c is not None
    centre = c.centres[c.sphere]
    towards = c.obstacle - centre
    surface = centre + towards / max(float(np.linalg.norm(towards)), 1e-12) * c.radius
    when = f" at t = {c.t:.2f} s" if c.t is not None else ""
    label = f"closest: {_mm(c.clearance)}{when}"
    exact = float(np.linalg.norm(towards)) - c.radius
    mesh = spheres_mesh(c.centres, scene.radii)
    return [
        _mesh(
            mesh,
            count,
            name="at the closest approach",
            color="#8e44ad",
            opacity=0.35,
            showlegend=True,
        ),
        {
            "type": "scatter3d",
            "mode": "lines+markers+text",
            **_xyz(np.stack([surface, c.obstacle])),
            "name": label,
            "text": ["", label],
            "textposition": "top center",
            "textfont": {"color": "#b00020", "size": 14},
            "line": {"color": "#b00020", "width": 6},
            "marker": {"size": 5, "color": "#b00020"},
            "hovertext": [
                f"sphere {c.sphere} (r = {_mm(c.radius)}), its surface",
                f"the nearest cloud point, {_mm(exact)} from the sphere's surface",
            ],
            "hoverinfo": "text",
        },
    ]


def _bounds(extent: list[Array]) -> tuple[Array, Array]:
    pts = np.vstack([e.reshape(-1, 3) for e in extent if e.size])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.03 * float(np.max(hi - lo))
    return lo - pad, hi + pad


def _scene_layout(lo: Array, hi: Array, camera: CameraView | None) -> dict[str, Any]:
    """Equal scales on the three axes, fixed ranges (the view must not jump while the robot
    moves), seen from the camera's side (turned 30 degrees about z, so that the camera's
    pyramid shows as one)."""
    span = hi - lo
    ratio = span / float(span.max())
    eye = np.array([1.25, -1.25, 1.0])
    if camera is not None:
        c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
        turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        d = turn @ (camera.T_base_cam[:3, 3] - (lo + hi) / 2) / span * ratio  # normalized box
        eye = 1.8 * d / max(float(np.linalg.norm(d)), 1e-9)
    axes = {
        f"{name}axis": {"range": [float(lo[k]), float(hi[k])], "title": {"text": f"{name} (m)"}}
        for k, name in enumerate("xyz")
    }
    return {
        **axes,
        "aspectmode": "manual",
        "aspectratio": dict(zip("xyz", ratio.tolist(), strict=True)),
        "camera": {"eye": dict(zip("xyz", eye.tolist(), strict=True))},
    }


def _controls(scene: Scene3D) -> dict[str, Any]:
    """Play/pause and a slider over the frames (named by their index)."""
    n = len(scene.centres)
    if scene.times is not None and n > 1:
        step_ms = max(20.0, 1000 * float(scene.times[-1] - scene.times[0]) / (n - 1))
        prefix, suffix = "t = ", " s"
    else:
        step_ms, prefix, suffix = 60.0, "along the path: ", " %"
    play = {
        "frame": {"duration": step_ms, "redraw": True},
        "transition": {"duration": 0},
        "fromcurrent": True,
    }
    pause = {"frame": {"duration": 0, "redraw": False}, "mode": "immediate"}
    jump = {"frame": {"duration": 0, "redraw": True}, "mode": "immediate"}
    buttons = [
        {"label": "play", "method": "animate", "args": [None, play]},
        {"label": "pause", "method": "animate", "args": [[None], pause]},
    ]
    return {
        "updatemenus": [
            {
                "type": "buttons",
                "direction": "left",
                "x": 0.0,
                "y": 0.0,
                "xanchor": "left",
                "yanchor": "top",
                "pad": {"t": 40, "r": 10},
                "buttons": buttons,
            }
        ],
        "sliders": [
            {
                "x": 0.12,
                "len": 0.88,
                "y": 0.0,
                "currentvalue": {"prefix": prefix, "suffix": suffix},
                "steps": [
                    {"label": _label(scene, k), "method": "animate", "args": [[str(k)], jump]}
                    for k in range(n)
                ],
            }
        ],
    }


def scene_html(scene: Scene3D) -> str:
    """The view as an HTML fragment (a ``div`` and its scripts), plotly.js inline once: the
    page that holds it needs nothing from the network."""
    import plotly.io as pio  # type: ignore[import-untyped]

    text: str = pio.to_html(
        scene_figure(scene),
        validate=False,
        full_html=False,
        include_plotlyjs=True,
        div_id=DIV_ID,
        auto_play=False,
        config={"displaylogo": False, "responsive": True},
    )
    return text
