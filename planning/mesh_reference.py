"""The ground truth the sphere checker is measured against: PyBullet with the URDF's real
collision meshes.

Each link's mesh is loaded as a concave triangle mesh (PyBullet would otherwise replace it by
its convex hull) on a static body that is placed at the link's pose from Pinocchio; the
obstacles form one compound body. A configuration collides when any link mesh touches any
obstacle (closest distance <= 0).
"""

from __future__ import annotations

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.primitives import Box, Cylinder, PrimitiveWorld, Sphere
from planning.robot_model import RobotModel


class MeshReference:
    """Exact mesh-versus-primitive collision queries for one robot and one world."""

    def __init__(
        self, robot: RobotModel, world: PrimitiveWorld, ignored_links: tuple[str, ...] | None = None
    ) -> None:
        if len(world) == 0:
            raise PlanningError("the mesh reference needs at least one obstacle")
        self.robot = robot
        self.client = pb.connect(pb.DIRECT)
        ignored = robot.config.world_ignored_links if ignored_links is None else ignored_links
        self.link_bodies: dict[str, int] = {}
        for name, mesh in robot.link_meshes.items():
            if name in ignored:
                continue
            shape = pb.createCollisionShape(
                pb.GEOM_MESH,
                vertices=np.asarray(mesh.vertices, float).tolist(),
                indices=np.asarray(mesh.faces, np.int32).ravel().tolist(),
                flags=pb.GEOM_FORCE_CONCAVE_TRIMESH,
                physicsClientId=self.client,
            )
            self.link_bodies[name] = pb.createMultiBody(
                baseMass=0, baseCollisionShapeIndex=shape, physicsClientId=self.client
            )
        self.obstacle_bodies = self._obstacle_bodies(world)

    def _obstacle_bodies(self, world: PrimitiveWorld) -> list[int]:
        types, kwargs_list, positions, orientations = [], [], [], []
        for prim in world.primitives:
            if isinstance(prim, Box):
                types.append(pb.GEOM_BOX)
                kwargs_list.append({"halfExtents": (prim.size / 2).tolist()})
                pose = prim.pose
            elif isinstance(prim, Cylinder):
                types.append(pb.GEOM_CYLINDER)
                kwargs_list.append({"radius": prim.radius, "height": prim.height})
                pose = prim.pose
            elif isinstance(prim, Sphere):
                types.append(pb.GEOM_SPHERE)
                kwargs_list.append({"radius": prim.radius})
                pose = np.eye(4)
                pose[:3, 3] = prim.center
            positions.append(pose[:3, 3].tolist())
            orientations.append(Rotation.from_matrix(pose[:3, :3]).as_quat().tolist())
        bodies = []
        # One body per obstacle: simpler than PyBullet's compound shapes, whose argument lists
        # must match across mixed primitive types.
        for t, kw, pos, orn in zip(types, kwargs_list, positions, orientations, strict=True):
            shape = pb.createCollisionShape(t, physicsClientId=self.client, **kw)
            bodies.append(
                pb.createMultiBody(
                    baseMass=0,
                    baseCollisionShapeIndex=shape,
                    basePosition=pos,
                    baseOrientation=orn,
                    physicsClientId=self.client,
                )
            )
        return bodies

    def collides(self, q: Array) -> bool:
        """True if any link mesh touches or penetrates any obstacle at configuration q."""
        poses = self.robot.link_poses(q)
        for name, body in self.link_bodies.items():
            T = poses[name]
            pb.resetBasePositionAndOrientation(
                body,
                T[:3, 3].tolist(),
                Rotation.from_matrix(T[:3, :3]).as_quat().tolist(),
                physicsClientId=self.client,
            )
        for body in self.link_bodies.values():
            for obstacle in self.obstacle_bodies:
                if pb.getClosestPoints(body, obstacle, 0.0, physicsClientId=self.client):
                    return True
        return False

    def close(self) -> None:
        if pb.isConnected(self.client):
            pb.disconnect(self.client)

    def __enter__(self) -> MeshReference:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
