"""Render a synthetic scene into a bag in a RealSense layout, with ground truth beside it."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from gaide.synthetic.raycast import RaycastScene, Texture
from gaide.synthetic.scene import SyntheticScene, obstacle_meshes, target_plate
from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import BagError, ConfigError
from gaide_core.joints import JointStates
from gaide_core.text_io import load_yaml
from gaide_core.transforms import to_xyz_quat
from gaide_core.types import Array
from perception.bag_writer import write_bag
from perception.frames import BagLayout, Frames, ImageStream
from planning.robot_model import RobotModel

log = logging.getLogger(__name__)

FRAME_PERIOD_NS = 33_333_333  # 30 Hz
START_NS = 1_700_000_000_000_000_000
_SUBPIXELS = np.array([[-0.25, -0.25], [0.25, -0.25], [-0.25, 0.25], [0.25, 0.25]])


def render_state(
    scene: SyntheticScene, robot: RobotModel, q: Array, rng: np.random.Generator
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint16]]:
    """Color (H, W, 3) RGB and raw depth (H, W) of the scene with the robot at ``q``."""
    rc = RaycastScene()
    for mesh in obstacle_meshes(scene):
        rc.add(mesh, (0.62, 0.55, 0.45))
    poses = robot.link_poses(q)
    for name, mesh in robot.link_meshes.items():
        rc.add(mesh.copy().apply_transform(poses[name]), (0.35, 0.45, 0.6))
    plate, extent = target_plate(scene.target)
    T_base_target = scene.target_pose(robot, q)
    texture = scene.target.texture(px_per_m=4000.0)
    rc.add(
        plate.copy().apply_transform(T_base_target),
        (1.0, 1.0, 1.0),
        Texture(texture.image, extent, T_base_target),
    )
    cam = scene.camera
    color = rc.cast(cam.color, cam.T_base_cam, _SUBPIXELS)["rgb"].mean(axis=0)
    color = np.clip(color * 255.0 + rng.normal(0, 1.5, color.shape), 0, 255).astype(np.uint8)
    hit = rc.cast(cam.depth, cam.T_base_depth, np.zeros((1, 2)))
    depth = cam.noise.apply(hit["z"][0], hit["cos"][0], rng)
    return color, depth


def record_scene(
    scene: SyntheticScene,
    robot: RobotModel,
    path: str | Path,
    rng: np.random.Generator,
    *,
    layout: BagLayout = BagLayout.SDK,
    ros_version: int = 1,
    storage: str = "sqlite3",
    progress: Callable[..., Any] | None = None,
) -> tuple[Path, Path]:
    """Render every state, write the bag and its ground truth; returns both paths."""
    colors, depths = [], []
    states = progress(scene.joint_states, desc="rendering") if progress else scene.joint_states
    for q in states:
        c, d = render_state(scene, robot, q, rng)
        colors.append(c)
        depths.append(d)
    n = len(colors)
    stamps = START_NS + np.arange(n, dtype=np.int64) * FRAME_PERIOD_NS
    cam = scene.camera
    frames = Frames(
        source=Path(path),
        layout=layout,
        depth=ImageStream(
            cam.depth, tuple(depths), stamps + 1_000_000, "camera_depth_optical_frame"
        ),
        color=ImageStream(cam.color, tuple(colors), stamps, "camera_color_optical_frame"),
        depth_units=cam.noise.depth_units,
        T_color_depth=cam.T_color_depth,
        joint_states=JointStates.from_stamps(
            robot.joint_names, stamps, np.asarray(scene.joint_states, float), error=BagError
        ),
    )
    bag = write_bag(path, frames, layout=layout, ros_version=ros_version, storage=storage)
    truth = ground_truth_path(bag)
    _write_yaml(truth, ground_truth(scene, robot))
    if scene.T_base_target is not None:
        # what a user measures for fixed-target calibration: the target and where it is
        _write_yaml(
            target_pose_path(bag),
            {"target": scene.target.to_dict(), "T_base_target": _pose(scene.T_base_target)},
        )
    return bag, truth


def _write_yaml(path: Path, data: dict[str, Any]) -> None:
    write_bytes_atomic(path, yaml.safe_dump(data, sort_keys=False).encode(), BagError)


def target_pose_path(bag: str | Path) -> Path:
    bag = Path(bag)
    return bag.parent / f"{bag.name.removesuffix('.bag')}.target_pose.yaml"


def ground_truth_path(bag: str | Path) -> Path:
    bag = Path(bag)
    return bag.parent / f"{bag.name.removesuffix('.bag')}.ground_truth.yaml"


def _pose(T: Array) -> dict[str, Any]:
    xyz, quat = to_xyz_quat(T)
    return {"matrix": np.round(T, 9).tolist(), "xyz": xyz.tolist(), "quat_xyzw": quat.tolist()}


def ground_truth(scene: SyntheticScene, robot: RobotModel) -> dict[str, Any]:
    cam = scene.camera
    out: dict[str, Any] = {
        "mode": scene.mode,
        "T_base_cam": _pose(cam.T_base_cam),
        "T_color_depth": _pose(cam.T_color_depth),
        "color_K": cam.color.K.tolist(),
        "depth_K": cam.depth.K.tolist(),
        "size": [cam.color.width, cam.color.height],
        "depth_units": cam.noise.depth_units,
        "depth_sigma_at_1m": cam.noise.sigma_at_1m,
        "target": scene.target.to_dict(),
        "joint_names": list(robot.joint_names),
        "joint_states": np.asarray(scene.joint_states).tolist(),
        "world": scene.truth_world().to_dict(),
    }
    if scene.T_base_target is not None:
        out["T_base_target"] = _pose(scene.T_base_target)
    if scene.T_flange_target is not None:
        out["T_flange_target"] = _pose(scene.T_flange_target)
        out["flange"] = scene.flange
    return out


def load_ground_truth(path: str | Path) -> dict[str, Any]:
    source = Path(path)
    data = load_yaml(source, "ground truth", ConfigError)
    if not isinstance(data, dict) or "T_base_cam" not in data:
        raise ConfigError(f"{source} is not a ground-truth file (no T_base_cam)")
    return data
