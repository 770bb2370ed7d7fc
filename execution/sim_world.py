"""The robot and its scene in PyBullet (DIRECT: no window), for simulated execution.

The robot is the URDF the robot config names, loaded with a fixed base at ``T_world_base``;
its mesh URIs (``package://``, relative paths) are resolved as Pinocchio resolves them and its
visual geometry and Gazebo tags are dropped (a temporary copy; the original is untouched).
The scene: analytic primitives as static boxes, cylinders and spheres, one body each (as
:class:`planning.mesh_reference.MeshReference` builds them), or a point cloud as static voxel
boxes (one box per occupied cell of ``voxel`` m).
"""

from __future__ import annotations

import logging
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from gaide_core.errors import ExecutionError
from gaide_core.native_output import quiet_native_output
from gaide_core.types import Array
from planning.primitives import Box, Cylinder, PrimitiveWorld, Sphere
from planning.robot_config import resolve_uri
from planning.robot_model import RobotModel

with quiet_native_output():  # its import prints a build-time banner on stdout
    import pybullet as pb

log = logging.getLogger(__name__)


def _bare_urdf(robot: RobotModel, folder: Path) -> Path:
    """A copy of the robot's URDF with absolute mesh paths, no visual, Gazebo or joint
    dynamics tags, and a token inertia for links that have none."""
    cfg = robot.config
    try:
        root = ET.parse(cfg.urdf).getroot()
    except (ET.ParseError, OSError) as err:
        raise ExecutionError(f"URDF {cfg.urdf} cannot be read: {err}") from err
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
        if link.find("inertial") is None and _moved_by_a_joint(root, link.get("name", "")):
            # PyBullet gives a link without <inertial> 1 kg and 1 kg m^2 (a tool frame at
            # the flange then needs more torque than the arm has): give it next to nothing.
            inertial = ET.SubElement(link, "inertial")
            ET.SubElement(inertial, "mass", value="0.001")
            ET.SubElement(
                inertial, "inertia", ixx="1e-7", iyy="1e-7", izz="1e-7", ixy="0", ixz="0", iyz="0"
            )
    for tag in ("gazebo", "transmission"):
        for el in root.findall(tag):
            root.remove(el)
    # Joint damping and friction are not modelled (execution.servo): PyBullet applies a
    # URDF's damping explicitly, which light wrist links cannot take at 500 Hz (an xArm7's
    # joint 7: damping 2 N m s, inertia 2e-4 kg m^2; the arm shook apart holding still).
    for joint in root.iter("joint"):
        for dynamics in joint.findall("dynamics"):
            joint.remove(dynamics)
    for mesh in root.iter("mesh"):
        uri = mesh.get("filename", "")
        mesh.set("filename", str(resolve_uri(uri, cfg.urdf.parent, cfg.package_dirs)))
    out = folder / cfg.urdf.name
    ET.ElementTree(root).write(out)
    return out


def _moved_by_a_joint(root: ET.Element, link: str) -> bool:
    """True unless ``link`` is the URDF's root (PyBullet's fixed base keeps it massless)."""
    return any(el.get("link") == link for el in root.iterfind("joint/child"))


class SimWorld:
    """A PyBullet client holding the robot and the scene; close it (or use ``with``)."""

    def __init__(
        self,
        robot: RobotModel,
        *,
        primitives: PrimitiveWorld | None = None,
        cloud: Array | None = None,
        voxel: float = 0.02,
        rate_hz: float = 500.0,
        gravity: bool = True,
    ) -> None:
        if primitives is not None and cloud is not None:
            raise ExecutionError("give the scene as primitives or as a cloud, not both")
        self.robot = robot
        self.client = pb.connect(pb.DIRECT)
        try:
            pb.setTimeStep(1.0 / rate_hz, physicsClientId=self.client)
            pb.setGravity(0, 0, -9.81 if gravity else 0.0, physicsClientId=self.client)
            self._load_robot()
            self.scene_labels: dict[int, str] = {}
            self.voxel_bodies: set[int] = set()
            self.voxel = voxel
            if primitives is not None:
                self._add_primitives(primitives)
            if cloud is not None:
                self._add_voxels(np.asarray(cloud, float), voxel)
        except Exception:
            self.close()
            raise

    # -- building ------------------------------------------------------------------------

    def _load_robot(self) -> None:
        robot, c = self.robot, self.client
        with tempfile.TemporaryDirectory(prefix="gaide-urdf-") as tmp:
            urdf = _bare_urdf(robot, Path(tmp))
            T = robot.T_world_base
            try:
                self.body = pb.loadURDF(
                    str(urdf),
                    basePosition=T[:3, 3].tolist(),
                    baseOrientation=Rotation.from_matrix(T[:3, :3]).as_quat().tolist(),
                    useFixedBase=True,
                    physicsClientId=c,
                )
            except pb.error as err:
                raise ExecutionError(f"PyBullet cannot load {robot.config.urdf}: {err}") from err
        by_name: dict[str, int] = {}
        self.link_names: dict[int, str] = {
            -1: pb.getBodyInfo(self.body, physicsClientId=c)[0].decode()
        }
        self.effort_limits = np.zeros(robot.dof)
        for j in range(pb.getNumJoints(self.body, physicsClientId=c)):
            info = pb.getJointInfo(self.body, j, physicsClientId=c)
            by_name[info[1].decode()] = j
            self.link_names[j] = info[12].decode()
        missing = [n for n in robot.joint_names if n not in by_name]
        if missing:
            raise ExecutionError(f"PyBullet's model of {robot.config.urdf} lacks joints {missing}")
        self.joints = [by_name[n] for n in robot.joint_names]
        for i, j in enumerate(self.joints):
            effort = pb.getJointInfo(self.body, j, physicsClientId=c)[10]
            self.effort_limits[i] = effort if effort > 0 else 1000.0
        # PyBullet drives every joint with a velocity motor by default: switch those off.
        pb.setJointMotorControlArray(
            self.body, self.joints, pb.VELOCITY_CONTROL, forces=[0.0] * len(self.joints),
            physicsClientId=c,
        )  # fmt: skip
        # Locked joints (a gripper's fingers) stand at their values and are held there.
        for name, value in robot.config.locked_joints.items():
            if name in by_name:
                pb.resetJointState(self.body, by_name[name], value, physicsClientId=c)
                pb.setJointMotorControl2(
                    self.body, by_name[name], pb.POSITION_CONTROL, targetPosition=value,
                    physicsClientId=c,
                )  # fmt: skip

    def _add_body(self, shape: int, position: Array, orientation: Array, label: str) -> None:
        body = pb.createMultiBody(
            baseMass=0,
            baseCollisionShapeIndex=shape,
            basePosition=position.tolist(),
            baseOrientation=orientation.tolist(),
            physicsClientId=self.client,
        )
        self.scene_labels[body] = label

    def _add_primitives(self, world: PrimitiveWorld) -> None:
        c = self.client
        for i, prim in enumerate(world.primitives):
            if isinstance(prim, Sphere):
                shape = pb.createCollisionShape(
                    pb.GEOM_SPHERE, radius=prim.radius, physicsClientId=c
                )
                self._add_body(shape, prim.center, np.array([0, 0, 0, 1.0]), f"sphere {i}")
                continue
            if isinstance(prim, Box):
                shape = pb.createCollisionShape(
                    pb.GEOM_BOX, halfExtents=(prim.size / 2).tolist(), physicsClientId=c
                )
                label = f"box {i}"
            elif isinstance(prim, Cylinder):
                shape = pb.createCollisionShape(
                    pb.GEOM_CYLINDER, radius=prim.radius, height=prim.height, physicsClientId=c
                )
                label = f"cylinder {i}"
            quat = Rotation.from_matrix(prim.pose[:3, :3]).as_quat()
            self._add_body(shape, prim.pose[:3, 3], quat, label)

    def _add_voxels(self, points: Array, voxel: float) -> None:
        if points.ndim != 2 or points.shape[1] != 3 or not np.all(np.isfinite(points)):
            raise ExecutionError(
                f"a cloud must be finite points of shape (N, 3), got {points.shape}"
            )
        if not voxel > 0:
            raise ExecutionError(f"voxel must be > 0 m, got {voxel}")
        cells = np.unique(np.floor(points / voxel).astype(np.int64), axis=0)
        centres = (cells + 0.5) * voxel
        # Static bodies of 16 boxes each (the most one createCollisionShapeArray keeps): a
        # step costs per body (1,800 one-box bodies: ~4 ms a step; 115 of 16: ~0.1 ms).
        c = self.client
        for s in range(0, len(centres), 16):
            part = centres[s : s + 16]
            shape = pb.createCollisionShapeArray(
                shapeTypes=[pb.GEOM_BOX] * len(part),
                halfExtents=[[voxel / 2] * 3] * len(part),
                collisionFramePositions=part.tolist(),
                physicsClientId=c,
            )
            body = int(
                pb.createMultiBody(baseMass=0, baseCollisionShapeIndex=shape, physicsClientId=c)
            )
            self.scene_labels[body] = "voxel"
            self.voxel_bodies.add(body)
        self.voxel = voxel
        log.debug("cloud: %d points as %d voxel boxes of %.3f m", len(points), len(centres), voxel)

    # -- running -------------------------------------------------------------------------

    def reset(self, q: Array) -> None:
        """Put the robot at configuration q (dof,) rad, at rest."""
        for j, value in zip(self.joints, q.tolist(), strict=True):
            pb.resetJointState(self.body, j, value, 0.0, physicsClientId=self.client)

    def command(self, q: Array, qd: Array, position_gain: float, velocity_gain: float) -> None:
        """Position control towards q (rad) with velocity feed-forward qd (rad/s), each joint
        limited to its URDF effort."""
        n = len(self.joints)
        pb.setJointMotorControlArray(
            self.body,
            self.joints,
            pb.POSITION_CONTROL,
            targetPositions=q.tolist(),
            targetVelocities=qd.tolist(),
            positionGains=[position_gain] * n,
            velocityGains=[velocity_gain] * n,
            forces=self.effort_limits.tolist(),
            physicsClientId=self.client,
        )

    def step(self) -> None:
        pb.stepSimulation(physicsClientId=self.client)

    def state(self) -> tuple[Array, Array]:
        """Joint positions (rad) and velocities (rad/s), (dof,) each."""
        states = pb.getJointStates(self.body, self.joints, physicsClientId=self.client)
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def contacts(self, ignored_links: tuple[str, ...] = ()) -> list[tuple[str, str, float]]:
        """(robot link, scene body label, distance m) of the robot-scene contacts of the last
        step: touching or penetrating, with a normal force (PyBullet's solver keeps
        penetrations near 1e-5 m, so the force, not the depth, tells a contact)."""
        out = []
        for pt in pb.getContactPoints(bodyA=self.body, physicsClientId=self.client):
            other, link, distance, force = pt[2], pt[3], pt[8], pt[9]
            if other not in self.scene_labels or distance > 0.0 or force <= 0.0:
                continue
            name = self.link_names.get(link, str(link))
            if name in ignored_links:
                continue
            label = self.scene_labels[other]
            if other in self.voxel_bodies:  # the box holding the contact point
                inside = np.asarray(pt[6]) - 0.25 * self.voxel * np.asarray(pt[7])
                centre = (np.floor(inside / self.voxel) + 0.5) * self.voxel
                label = f"voxel at {np.round(centre, 3).tolist()}"
            out.append((name, label, float(distance)))
        return out

    def close(self) -> None:
        if pb.isConnected(self.client):
            pb.disconnect(self.client)

    def __enter__(self) -> SimWorld:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
