"""The first stages of a run: the robot and the settings that depend on it, the camera's pose
in the base frame, and the scene cloud.

Each stage function takes the runner's record of the stage, fills in its figures, writes its
files through :meth:`~gaide.pipeline.runner.StageRunner.commit` and returns what the next
stages need.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import yaml

from calibration.result import CalibrationResult, load_calibration
from calibration.targets import parse_target
from gaide.pipeline import figures
from gaide.pipeline.config import RunCfg
from gaide.pipeline.endpoints import FORMS, Endpoint, EndpointKind, parse_endpoint
from gaide.pipeline.runner import StageRecord, StageRunner
from gaide_core.errors import CalibrationError, ConfigError, ModelError
from gaide_core.transforms import from_xyz_quat, to_xyz_quat
from gaide_core.types import Array
from perception.cloud import SceneCloud, save_ply
from planning.robot_model import RobotModel
from planning.robot_setup import robot_and_spheres
from planning.sphere_model import SphereModel

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Setup:
    robot: RobotModel
    spheres: SphereModel
    start: Endpoint
    goal: Endpoint
    planner: str  # the planner the run uses ("auto" resolved)
    # The arm recorded in the bag: the run's robot, or perception.bag_robot's, which the
    # run's robot replaces (its joint states are then not the run's robot's).
    bag_robot: RobotModel
    bag_spheres: SphereModel


@dataclass(frozen=True)
class CameraPose:
    T_base_cam: Array  # (4, 4) color camera in the base frame
    source: str  # "calibrated", "calibration file", "given"
    result: CalibrationResult | None  # None when the pose was given


@dataclass(frozen=True)
class Sensed:
    cloud: SceneCloud
    recorded: Array | None  # (dof,) rad, the bag's joint state (None: the bag has none)


def setup_stage(cfg: RunCfg, record: StageRecord) -> Setup:
    """Load the robot; check what can be checked before the long stages (after
    :func:`gaide.pipeline.run.check_inputs`): endpoints that parse, the neural planner's
    weights."""
    assert cfg.bag is not None and cfg.planning.goal is not None  # run.check_inputs
    robot, spheres = robot_and_spheres(cfg.robot)
    start = parse_endpoint(cfg.planning.start, robot, "start")
    goal = parse_endpoint(cfg.planning.goal, robot, "goal")
    for ep in (start, goal):
        if ep.kind is EndpointKind.RECORDED and cfg.perception.bag_robot is not None:
            raise ConfigError(
                f"{ep.what} 'recorded': the bag records another robot "
                f"(perception.bag_robot={cfg.perception.bag_robot}); give --{ep.what} as {FORMS}"
            )
    planner = _resolve_planner(cfg, robot)
    _check_weights(cfg, planner)
    record.figures.update(
        robot=str(robot.config.urdf.name),
        dof=robot.dof,
        spheres=len(spheres),
        planner=planner,
    )
    if planner != cfg.planning.planner:
        record.figures["planner_auto"] = (
            "GAIDE's weights fit this robot" if planner == AUTO_NEURAL else _NO_WEIGHTS
        )
    bag_robot, bag_spheres = (
        (robot, spheres)
        if cfg.perception.bag_robot is None
        else robot_and_spheres(cfg.perception.bag_robot)
    )
    return Setup(robot, spheres, start, goal, planner, bag_robot, bag_spheres)


AUTO_NEURAL = "gaide-hybrid"
_NO_WEIGHTS = "no GAIDE weights fit this robot: the compiled RRT-Connect plans"


def _resolve_planner(cfg: RunCfg, robot: RobotModel) -> str:
    """``auto``: gaide-hybrid when its weights (given or shipped) load for this robot, else
    rrtc; any other name as given."""
    if cfg.planning.planner != "auto":
        return cfg.planning.planner
    from gaide_core.errors import GaideError
    from planning.neural.checkpoint import load_checkpoint, shipped_checkpoint

    weights = cfg.planning.checkpoint or shipped_checkpoint("gaide")
    try:
        load_checkpoint(weights, robot, kind="gaide")
    except GaideError as err:
        log.warning("planner auto: %s (%s)", _NO_WEIGHTS, err)
        return "rrtc"
    return AUTO_NEURAL


def _check_weights(cfg: RunCfg, name: str) -> None:
    from planning.registry import HYBRID, NEURAL

    if name not in NEURAL + HYBRID:
        return
    if cfg.planning.checkpoint is not None:
        weights = Path(cfg.planning.checkpoint)
    else:
        from planning.neural.checkpoint import shipped_checkpoint

        weights = shipped_checkpoint(name.removesuffix("-hybrid"))
    if not weights.is_file():
        raise ModelError(
            f"planner '{name}' needs weights {weights}, which do not exist: give "
            "--checkpoint FILE (from `gaide train`) or a classical planner (--planner rrtconnect)"
        )


def given_camera(cfg: RunCfg) -> CameraPose:
    """The camera pose ``calibration.T_base_cam`` gives (no calibration)."""
    v = cfg.calibration.T_base_cam
    if v is None:
        raise ConfigError("calibration.T_base_cam is not set")
    norm = float(np.linalg.norm(v[3:]))
    if not 0.9 < norm < 1.1:
        raise ConfigError(
            f"calibration.T_base_cam: qx, qy, qz, qw must be a unit quaternion, its norm is "
            f"{norm:.3f}"
        )
    return CameraPose(from_xyz_quat(v[:3], np.asarray(v[3:]) / norm), "given", None)


def calibration_stage(
    cfg: RunCfg, robot: RobotModel, runner: StageRunner, record: StageRecord
) -> CameraPose:
    """``T_base_cam`` from a calibration file, a given pose, or the bag's target."""
    from gaide.flows.calibrate import calibrate_bag
    from gaide.synthetic.record import target_pose_path

    c = cfg.calibration
    if c.calib is not None:
        result = load_calibration(c.calib)
        source = "calibration file"
        overlay = None
    else:
        assert cfg.bag is not None  # checked by run.check_inputs
        target_pose = c.target_pose
        if c.mode == "fixed" and target_pose is None:
            beside = target_pose_path(cfg.bag)
            if not beside.is_file():
                raise CalibrationError(
                    f"fixed-target calibration needs the target's pose in the base frame: none "
                    f"given and {beside} does not exist; give --target-pose FILE, or skip "
                    "calibrating with --calib FILE or --T-base-cam x,y,z,qx,qy,qz,qw"
                )
            target_pose = str(beside)
        run = calibrate_bag(
            cfg.bag,
            mode=c.mode,
            robot=robot,
            target=parse_target(c.target) if c.target else None,
            target_pose=target_pose,
            max_frames=c.max_frames,
        )
        result, source, overlay = run.result, "calibrated", run.overlay
    files: dict[str, bytes] = {
        "calibration.yaml": yaml.safe_dump(
            result.to_dict(), sort_keys=False, default_flow_style=None
        ).encode()
    }
    if overlay is not None:
        files["calibration_overlay.png"] = _png(overlay)
    runner.commit(record, files)
    xyz, quat = to_xyz_quat(result.T_base_cam)
    record.figures.update(
        source=source,
        reprojection_rms_px=float(result.reprojection_rms_px),
        frames_used=sum(f.used for f in result.frames),
        frames=len(result.frames),
        T_base_cam_xyz=np.round(xyz, 5).tolist(),
        T_base_cam_quat_xyzw=np.round(quat, 6).tolist(),
    )
    return CameraPose(result.T_base_cam, source, result)


def _png(image: npt.NDArray[np.uint8]) -> bytes:
    import cv2

    img = np.asarray(cv2.cvtColor(image, cv2.COLOR_RGB2BGR)) if image.ndim == 3 else image
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise CalibrationError(f"cannot encode the {image.shape} overlay as PNG")
    return bytes(buf.tobytes())


def perception_stage(
    cfg: RunCfg,
    setup: Setup,
    camera: CameraPose,
    runner: StageRunner,
    record: StageRecord,
) -> Sensed:
    """The scene cloud in the base frame, without the robot's own points."""
    from gaide.flows.perceive import perceive_bag

    p = cfg.perception
    assert cfg.bag is not None  # checked by run.check_inputs
    joints = None if p.joints is None else np.asarray(p.joints)
    calibration = camera.result if camera.result is not None else camera.T_base_cam
    cloud, _, q = perceive_bag(
        cfg.bag,
        calibration,
        setup.bag_robot,
        setup.bag_spheres,
        p,
        joints=joints,
        self_filter=p.self_filter,
        default_extrinsics=p.default_extrinsics,
    )
    picture = figures.cloud_png(
        cloud.points,
        cloud.colors,
        eye=camera.T_base_cam[:3, 3],
        title=f"scene cloud, base frame ({len(cloud):,} points)",
    )
    runner.commit(
        record,
        {"scene.ply": lambda tmp: save_ply(str(tmp), cloud), "scene.png": picture},
    )
    record.figures.update(
        points=len(cloud),
        counts=dict(cloud.counts),
        cloud_s=round(cloud.seconds, 3),
        recorded_joints=None if q is None else np.round(q, 6).tolist(),
        self_filter=bool(p.self_filter and q is not None),
    )
    recorded = q if joints is None and p.bag_robot is None else None
    return Sensed(cloud, recorded)
