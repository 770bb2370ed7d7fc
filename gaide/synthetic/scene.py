"""Synthetic workcells: obstacles, a calibration target, the robot and the camera."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from calibration.targets import Charuco, Target
from gaide.synthetic.camera import VirtualCamera, d435_like, look_at
from gaide_core.errors import ConfigError
from gaide_core.transforms import from_xyz_rpy, invert
from gaide_core.types import Array
from planning.collision import CollisionChecker
from planning.ik import IKCfg, solve_ik
from planning.primitives import Box, PrimitiveWorld, primitive_mesh
from planning.robot_model import RobotModel

TABLE_TOP = -0.02  # m: the robot stands on a 2 cm adapter plate on the table


@dataclass(frozen=True, kw_only=True)
class SyntheticScene:
    world: PrimitiveWorld  # obstacles in the base frame (the target's plate not included)
    target: Target
    joint_states: Array  # (N, dof): the robot's configuration in each recorded state
    camera: VirtualCamera
    T_base_target: Array | None = None  # fixed mode: target pose in the base frame
    T_flange_target: Array | None = None  # hand-eye mode: target pose in the flange frame
    flange: str = "tool0"

    def __post_init__(self) -> None:
        if (self.T_base_target is None) == (self.T_flange_target is None):
            raise ConfigError(
                "a scene has its target either fixed (T_base_target) or on the flange"
            )

    @property
    def mode(self) -> str:
        return "fixed" if self.T_base_target is not None else "hand-eye"

    def truth_world(self) -> PrimitiveWorld:
        """The obstacles plus, for a fixed target, its plate: every surface the camera sees
        except the robot's."""
        if self.T_base_target is None:
            return self.world
        plate, _ = target_plate(self.target)
        obb = plate.apply_transform(self.T_base_target).bounding_box_oriented
        box = Box(np.asarray(obb.primitive.extents), np.asarray(obb.primitive.transform))
        return PrimitiveWorld([*self.world.primitives, box])

    def target_pose(self, robot: RobotModel, q: Array) -> Array:
        if self.T_base_target is not None:
            return self.T_base_target
        assert self.T_flange_target is not None
        return robot.frame_pose(q, self.flange) @ self.T_flange_target


def target_plate(
    target: Target, thickness: float = 0.004
) -> tuple[trimesh.Trimesh, tuple[float, float, float, float]]:
    """The plate carrying the target, in the target frame: a thin box whose visible face is
    the target's z = 0 plane and whose body lies behind it (away from the viewer)."""
    texture = target.texture(px_per_m=2000.0)
    x0, x1, y0, y1 = texture.extent
    behind = -texture.viewed_from_z * thickness / 2
    plate = trimesh.creation.box(
        extents=(x1 - x0, y1 - y0, thickness),
        transform=from_xyz_rpy([(x0 + x1) / 2, (y0 + y1) / 2, behind], [0, 0, 0]),
    )
    return plate, texture.extent


def facing(target: Target, normal: Array, roll: float = 0.0) -> Array:
    """(3, 3) rotation of a target whose readable face looks along ``normal`` (unit, base
    frame), turned by ``roll`` (rad) about it: boards are read from their -z side."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    x = np.cross([0.0, 0.0, 1.0], n)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.array([1.0, 0.0, 0.0])
    y = np.cross(n, x)
    R = Rotation.from_rotvec(n * roll).as_matrix() @ np.stack([x, y, n], axis=1)
    if target.texture(px_per_m=200.0).viewed_from_z < 0:
        R = R @ np.diag([1.0, -1.0, -1.0])  # readable side is -z: turn the board over
    return R


def fixed_scene(robot: RobotModel, rng: np.random.Generator, *, frames: int = 5) -> SyntheticScene:
    """A table with boxes, a ChArUco board leaning towards the camera, the robot at rest."""
    # A 40 x 27 cm board seen obliquely from about 1 m: single-view PnP of a smaller board
    # seen face-on from further away tilts by ~0.7 deg (measured), i.e. ~17 mm at the camera.
    target: Target = Charuco(squares_x=9, squares_y=6, square_size=0.045, marker_size=0.034)
    color, depth = d435_like()
    camera = VirtualCamera(
        color=color, depth=depth, T_base_cam=look_at([1.15, -0.75, 0.65], [0.45, -0.25, 0.1])
    )
    # The board stands on the table, leaning back, turned 35 degrees away from the camera.
    centre = np.array([0.55, -0.35, TABLE_TOP + 0.12])
    to_cam = camera.T_base_cam[:3, 3] - centre
    to_cam[2] *= 0.5
    to_cam = Rotation.from_euler("z", 35, degrees=True).apply(to_cam)
    x0, x1, y0, y1 = target.texture(px_per_m=200.0).extent
    T_base_target = np.eye(4)
    T_base_target[:3, :3] = facing(target, to_cam / np.linalg.norm(to_cam))
    T_base_target[:3, 3] = centre - T_base_target[:3, :3] @ [(x0 + x1) / 2, (y0 + y1) / 2, 0.0]
    prims: list[Any] = [
        Box(np.array([1.4, 1.4, 0.04]), from_xyz_rpy([0.3, 0.0, TABLE_TOP - 0.02], [0, 0, 0]))
    ]
    for xy in ([0.45, 0.35], [-0.05, 0.5], [0.15, -0.55]):
        size = rng.uniform([0.08, 0.08, 0.06], [0.2, 0.2, 0.25])
        pos = np.asarray(xy) + rng.uniform(-0.04, 0.04, 2)
        prims.append(
            Box(size, from_xyz_rpy([*pos, TABLE_TOP + size[2] / 2], [0, 0, rng.uniform(-0.5, 0.5)]))
        )
    q = (
        robot.named_configuration("home")
        if "home" in robot.config.named_configurations
        else (robot.lower + robot.upper) / 2
    )
    return SyntheticScene(
        world=PrimitiveWorld(prims),
        target=target,
        joint_states=np.repeat(q[None], frames, axis=0),
        camera=camera,
        T_base_target=T_base_target,
    )


def hand_eye_scene(
    robot: RobotModel, checker_for: Any, rng: np.random.Generator, *, states: int = 12
) -> SyntheticScene:
    """A ChArUco board on the flange, shown to a fixed camera in ``states`` poses that turn
    about several axes (as hand-eye needs), each reached by collision-free IK.

    checker_for: function (world) -> CollisionChecker, so the robot avoids the table.
    """
    target: Target = Charuco(squares_x=5, squares_y=4, square_size=0.035, marker_size=0.026)
    x0, x1, y0, y1 = target_plate(target)[1]
    # board centred 2 cm in front of the flange, its readable face along the flange's z axis
    T_flange_target = np.eye(4)
    T_flange_target[:3, :3] = facing(target, np.array([0.0, 0.0, 1.0]))
    T_flange_target[:3, 3] = [0.0, 0.0, 0.02] - T_flange_target[:3, :3] @ [
        (x0 + x1) / 2,
        (y0 + y1) / 2,
        0.0,
    ]
    table = Box(np.array([1.4, 1.4, 0.04]), from_xyz_rpy([0.3, 0.0, TABLE_TOP - 0.02], [0, 0, 0]))
    world = PrimitiveWorld([table])
    checker: CollisionChecker = checker_for(world)
    color, depth = d435_like()
    camera = VirtualCamera(
        color=color, depth=depth, T_base_cam=look_at([1.3, -0.7, 0.8], [0.4, 0.0, 0.35])
    )
    cam_pos = camera.T_base_cam[:3, 3]
    qs: list[Array] = []
    seed = (
        robot.named_configuration("home") if "home" in robot.config.named_configurations else None
    )
    tries = 0
    while len(qs) < states:
        tries += 1
        if tries > 50 * states:
            raise ConfigError(f"found only {len(qs)} of {states} hand-eye poses the camera sees")
        centre = np.array([0.45, 0.0, 0.4]) + rng.uniform([-0.12, -0.2, -0.12], [0.12, 0.2, 0.15])
        to_cam = (cam_pos - centre) / np.linalg.norm(cam_pos - centre)
        tilt_axis = np.cross(to_cam, rng.normal(size=3))
        tilt_axis /= np.linalg.norm(tilt_axis)
        normal = Rotation.from_rotvec(tilt_axis * np.deg2rad(rng.uniform(10, 35))).apply(to_cam)
        T_base_target = np.eye(4)
        T_base_target[:3, :3] = facing(target, normal, roll=rng.uniform(-0.8, 0.8))
        T_base_target[:3, 3] = centre - T_base_target[:3, :3] @ [(x0 + x1) / 2, (y0 + y1) / 2, 0.0]
        T_base_flange = T_base_target @ invert(T_flange_target)
        sols = solve_ik(
            robot,
            T_base_flange,
            rng,
            cfg=IKCfg(restarts=8, max_solutions=1),
            checker=checker,
            seed=seed,
        )
        if sols:
            qs.append(sols[0])
    return SyntheticScene(
        world=world,
        target=target,
        joint_states=np.asarray(qs),
        camera=camera,
        T_flange_target=T_flange_target,
    )


def obstacle_meshes(scene: SyntheticScene) -> list[trimesh.Trimesh]:
    return [primitive_mesh(p) for p in scene.world.primitives]
