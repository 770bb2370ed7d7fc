from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from calibration.result import Mode, Setup
from calibration.targets import target_from_dict
from gaide.flows.calibrate import calibrate_bag
from gaide.flows.perceive import perceive_bag, recorded_configuration
from gaide.synthetic.record import load_ground_truth, record_scene, target_pose_path
from gaide.synthetic.scene import fixed_scene, hand_eye_scene
from gaide_core.errors import CalibrationError, PerceptionError
from gaide_core.transforms import invert, transform_error
from perception.bag_reader import read_bag
from perception.frames import BagLayout
from planning.checker import make_checker
from planning.primitives import PrimitiveWorld
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel
from tests.conftest import ROOT, run_cli, shared_data


@pytest.fixture(scope="module")
def fixed_bag(tmp_path_factory: pytest.TempPathFactory, robot: RobotModel) -> Path:
    rng = np.random.default_rng(5)
    scene = fixed_scene(robot, rng, frames=2)
    bag, _ = record_scene(scene, robot, tmp_path_factory.mktemp("rec") / "fixed.bag", rng)
    return bag


def test_recorder_writes_what_the_reader_reads(fixed_bag: Path, robot: RobotModel) -> None:
    frames = read_bag(fixed_bag)
    truth = load_ground_truth(fixed_bag.parent / "fixed.ground_truth.yaml")
    assert frames.layout is BagLayout.SDK and len(frames.depth or ()) == 2
    assert frames.joint_states is not None and frames.joint_states.names == robot.joint_names
    assert frames.color is not None
    np.testing.assert_allclose(frames.color.intrinsics.K, truth["color_K"])
    depth = frames.depth.images[0] if frames.depth else None
    assert depth is not None and 0.3 < (depth > 0).mean() < 0.99  # the rest looks past the table


def test_fixed_calibration_and_cloud_match_the_ground_truth(
    fixed_bag: Path, robot: RobotModel, spheres: SphereModel
) -> None:
    truth = load_ground_truth(fixed_bag.parent / "fixed.ground_truth.yaml")
    run = calibrate_bag(fixed_bag, mode="fixed", target_pose=target_pose_path(fixed_bag))
    dt, dr = transform_error(run.result.T_base_cam, np.asarray(truth["T_base_cam"]["matrix"]))
    assert dt < 0.002 and np.degrees(dr) < 0.2
    cloud, _, q = perceive_bag(fixed_bag, run.result, robot, spheres)
    assert q is not None and cloud.counts["robot_removed"] > 100
    err = np.abs(PrimitiveWorld.from_dict(truth["world"]).distance(cloud.points))
    assert np.median(err) < 0.01
    # the robot's own surface is gone: nothing left inside its (padded) spheres
    checker = make_checker(robot, spheres)
    centers = checker.sphere_centers(q[None])[0]
    d = np.linalg.norm(cloud.points[:, None] - centers[None], axis=-1) - checker.radii
    assert d.min() > 0.0


def test_eye_in_hand_calibration_places_the_camera_from_the_joints(
    fixed_bag: Path, robot: RobotModel, spheres: SphereModel
) -> None:
    """A camera on the flange: its pose is FK(recorded joints) @ T_flange_cam."""
    run = calibrate_bag(fixed_bag, mode="fixed", target_pose=target_pose_path(fixed_bag))
    q = recorded_configuration(read_bag(fixed_bag), robot)
    assert q is not None
    T_base_flange = robot.frame_pose(q, robot.config.end_effector)
    moved = replace(
        run.result,
        mode=Mode.HAND_EYE,
        setup=Setup.EYE_IN_HAND,
        T_base_cam=np.eye(4),  # where the camera was during calibration: not used
        T_flange_cam=invert(T_base_flange) @ run.result.T_base_cam,
        flange_frame=robot.config.end_effector,
    )
    fixed_cloud, _, _ = perceive_bag(fixed_bag, run.result, robot, spheres)
    eih_cloud, _, _ = perceive_bag(fixed_bag, moved, robot, spheres)
    np.testing.assert_allclose(eih_cloud.points, fixed_cloud.points, atol=1e-9)


def test_hand_eye_calibration_from_joint_states(
    tmp_path: Path, robot: RobotModel, spheres: SphereModel
) -> None:
    rng = np.random.default_rng(3)
    scene = hand_eye_scene(robot, lambda w: make_checker(robot, spheres, w), rng, states=7)
    bag, truth_path = record_scene(
        scene, robot, tmp_path / "he", rng, ros_version=2, storage="mcap"
    )
    truth = load_ground_truth(truth_path)
    run = calibrate_bag(bag, mode="hand-eye", robot=robot, target=target_from_dict(truth["target"]))
    dt, dr = transform_error(run.result.T_base_cam, np.asarray(truth["T_base_cam"]["matrix"]))
    assert dt < 0.005 and np.degrees(dr) < 0.5
    assert len(run.result.methods) == 5


def test_hand_eye_needs_joint_states(fixed_bag: Path, robot: RobotModel, tmp_path: Path) -> None:
    from dataclasses import replace

    from perception.bag_writer import write_bag

    frames = replace(read_bag(fixed_bag), joint_states=None)
    bare = write_bag(tmp_path / "bare.bag", frames, layout=BagLayout.SDK)
    with pytest.raises(CalibrationError, match="joint states"):
        calibrate_bag(
            bare,
            mode="hand-eye",
            robot=robot,
            target=target_from_dict("charuco:9x6,square=0.045,marker=0.034"),
        )


def test_calibration_for_another_camera_is_refused(
    fixed_bag: Path, robot: RobotModel, spheres: SphereModel
) -> None:
    from dataclasses import replace

    run = calibrate_bag(fixed_bag, mode="fixed", target_pose=target_pose_path(fixed_bag))
    other = replace(run.result, K=run.result.K * np.array([[1.2], [1.2], [1.0]]))
    with pytest.raises(PerceptionError, match="calibration is for a 640x480 camera"):
        perceive_bag(fixed_bag, other, robot, spheres)


def test_cli_calibrate_and_perceive(fixed_bag: Path, tmp_path: Path) -> None:
    calib = tmp_path / "calib.yaml"
    proc = run_cli(
        "calibrate",
        str(fixed_bag),
        "--target-pose",
        str(target_pose_path(fixed_bag)),
        "-o",
        str(calib),
        "--json",
        str(tmp_path / "cal.json"),
    )
    assert proc.returncode == 0, proc.stderr
    assert "reprojection RMS" in proc.stdout
    assert yaml.safe_load(calib.read_text())["T_base_cam"]["matrix"]
    assert (tmp_path / "calib.overlay.png").stat().st_size > 10_000
    ply = tmp_path / "scene.ply"
    proc = run_cli(
        "perceive",
        str(fixed_bag),
        "--calib",
        str(calib),
        "-o",
        str(ply),
        "--json",
        str(tmp_path / "per.json"),
    )
    assert proc.returncode == 0, proc.stderr
    figures = json.loads((tmp_path / "per.json").read_text())
    assert figures["points"] > 1000 and (tmp_path / "scene.png").stat().st_size > 10_000


def test_cli_failures_exit_per_stage_and_leave_nothing(fixed_bag: Path, tmp_path: Path) -> None:
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"not a bag at all" * 100)
    out = tmp_path / "c.yaml"
    proc = run_cli(
        "calibrate", str(junk), "--target-pose", str(target_pose_path(fixed_bag)), "-o", str(out)
    )
    assert proc.returncode == 3 and proc.stderr.count("\n") == 1
    assert not out.exists() and not (tmp_path / "c.overlay.png").exists()
    wrong = tmp_path / "wrong_target.yaml"
    pose = yaml.safe_load(target_pose_path(fixed_bag).read_text())
    pose["target"] = "tag36h11:id=300,size=0.08"
    wrong.write_text(yaml.safe_dump(pose))
    proc = run_cli("calibrate", str(fixed_bag), "--target-pose", str(wrong), "-o", str(out))
    assert proc.returncode == 4, proc.stderr
    assert not out.exists()
    ply = tmp_path / "s.ply"
    proc = run_cli(
        "perceive",
        str(fixed_bag),
        "--T-base-cam",
        "0,0,1,0,0,0,1",
        "--workspace",
        "5,5,5,6,6,6",
        "-o",
        str(ply),
    )
    assert proc.returncode == 5 and "workspace box" in proc.stderr
    assert not ply.exists()


def test_real_recording_gives_a_cloud_with_a_given_camera_pose(
    robot: RobotModel, spheres: SphereModel, tmp_path: Path
) -> None:
    bag = shared_data("realsense/librealsense_single_depth_color_640x480.bag")
    # camera 1 m above the base looking straight ahead along base x (no tag in that bag)
    T = np.array([[0, 0, 1.0, 0], [-1.0, 0, 0, 0], [0, -1.0, 0, 1.0], [0, 0, 0, 1]])
    from perception.cloud_cfg import CloudCfg

    cfg = CloudCfg(workspace_min=(-4, -4, -4), workspace_max=(4, 4, 4))
    cloud, _, q = perceive_bag(bag, T, robot, spheres, cfg, self_filter=False)
    assert q is None and len(cloud) > 5000
    # the recording spans 0.34..3.18 m of depth: in the base frame that is x
    assert cloud.points[:, 0].min() > 0.3 and cloud.points[:, 0].max() < 3.3


def test_shipped_sample_bag_matches_its_ground_truth() -> None:
    bag = ROOT / "bags" / "sample_workcell.bag"
    assert bag.stat().st_size < 10 * 2**20
    run = calibrate_bag(bag, mode="fixed", target_pose=target_pose_path(bag))
    truth = load_ground_truth(ROOT / "bags" / "sample_workcell.ground_truth.yaml")
    dt, dr = transform_error(run.result.T_base_cam, np.asarray(truth["T_base_cam"]["matrix"]))
    assert dt < 0.002 and np.degrees(dr) < 0.2
