"""Point clouds of a primitive world, as the networks see scenes: points sampled on the
obstacle surfaces, or the partial view of a virtual depth camera (what perception produces).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import open3d as o3d
import trimesh

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.primitives import PrimitiveWorld, primitive_mesh
from planning.robot_model import RobotModel


def surface_cloud(world: PrimitiveWorld, n: int, rng: np.random.Generator) -> Array:
    """(n, 3) points on the obstacles' visible surfaces, spread by area (base frame): faces
    buried inside another obstacle (a shelf board's end inside a side wall) are left out."""
    out = np.zeros((0, 3))
    for _ in range(8):
        pts = world.sample_surface(int(n * 1.5) + 16, rng)
        out = np.concatenate([out, pts[world.distance(pts) > -1e-6]])
        if len(out) >= n:
            return out[:n]
    raise PlanningError("the obstacles' surfaces are almost all buried inside each other")


def camera_view(
    world: PrimitiveWorld,
    rng: np.random.Generator,
    *,
    n: int = 4096,
    eye: Array | None = None,
    lookat: tuple[float, float, float] = (0.45, 0.0, 0.15),
    fov_deg: float = 70.0,
    size: tuple[int, int] = (160, 120),
    noise: float = 0.002,
) -> Array:
    """(<= n, 3) points a depth camera at ``eye`` (default: a random spot in front of and above
    the robot) sees of the world, with Gaussian noise of ``noise`` m, base frame."""
    if len(world) == 0:
        raise PlanningError("the world has no obstacles to view")
    if eye is None:
        a = rng.uniform(-0.9, 0.9)
        eye = np.array([1.3 * np.cos(a), 1.3 * np.sin(a), rng.uniform(0.6, 1.1)])
    scene = o3d.t.geometry.RaycastingScene()
    for p in world.primitives:
        mesh = primitive_mesh(p)
        tmesh = o3d.t.geometry.TriangleMesh()
        tmesh.vertex.positions = o3d.core.Tensor.from_numpy(
            np.ascontiguousarray(mesh.vertices, np.float32)
        )
        tmesh.triangle.indices = o3d.core.Tensor.from_numpy(
            np.ascontiguousarray(mesh.faces, np.int32)
        )
        scene.add_triangles(tmesh)

    def vec(v: npt.ArrayLike) -> o3d.core.Tensor:
        return o3d.core.Tensor.from_numpy(np.asarray(v, np.float32))

    rays = o3d.t.geometry.RaycastingScene.create_rays_pinhole(
        fov_deg=fov_deg,
        center=vec(lookat),
        eye=vec(eye),
        up=vec([0.0, 0.0, 1.0]),
        width_px=size[0],
        height_px=size[1],
    )
    hit = scene.cast_rays(rays)
    t = hit["t_hit"].numpy()
    r = rays.numpy()
    ok = np.isfinite(t)
    pts = r[ok][:, :3] + r[ok][:, 3:] * t[ok][:, None]
    pts = pts.astype(float) + rng.normal(0.0, noise, pts.shape)
    if len(pts) > n:
        pts = pts[rng.choice(len(pts), n, replace=False)]
    return pts


def posed_link_meshes(robot: RobotModel, q: Array) -> list[trimesh.Trimesh]:
    """Every link's collision mesh at configuration q, in the base frame."""
    poses = robot.link_poses(q)
    return [mesh.copy().apply_transform(poses[name]) for name, mesh in robot.link_meshes.items()]
