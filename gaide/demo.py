"""``gaide demo``: the main job on the embedded default, the sample bag in ``bags/``.

Calibrates the camera to the robot base from the board in the bag, builds the scene cloud
in the base frame without the robot's own points, and draws the robot's collision spheres in
that scene. Later stages (planning, timing, execution) extend it.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from calibration.overlay import save_png
from gaide.common import print_table, robot_and_spheres, write_json
from gaide.flows.calibrate import calibrate_bag
from gaide.flows.perceive import perceive_bag
from perception.cloud import save_ply
from perception.render import render_png
from planning.collision import SphereCollisionChecker
from planning.distance_field import CloudWorld
from planning.plot import render_scene

BAGS = Path(__file__).resolve().parents[1] / "bags"
SAMPLE_BAG = BAGS / "sample_workcell.bag"
SAMPLE_TARGET = BAGS / "sample_workcell.target_pose.yaml"


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("demo", help="run the main job on the shipped sample bag")
    p.add_argument("-o", "--out", default="out/demo", help="output folder")
    p.set_defaults(func=cmd_demo)


def cmd_demo(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    robot, spheres = robot_and_spheres(None)
    run = calibrate_bag(SAMPLE_BAG, mode="fixed", target_pose=SAMPLE_TARGET)
    run.result.save_yaml(out / "calibration.yaml")
    save_png(out / "calibration_overlay.png", run.overlay)
    cloud, _, q = perceive_bag(SAMPLE_BAG, run.result, robot, spheres)
    save_ply(str(out / "scene.ply"), cloud)
    render_png(out / "scene.png", cloud.points, cloud.colors)
    checker = SphereCollisionChecker(robot, spheres, CloudWorld(cloud.points))
    recorded = q if q is not None else robot.named_configuration("home")
    valid = bool(checker.config_valid(recorded[None])[0])
    render_scene(
        out / "robot_scene.png",
        checker,
        [recorded],
        cloud.points,
        title="UR5 collision spheres in the perceived scene",
    )
    res = run.result
    summary = {
        "bag": str(SAMPLE_BAG),
        "calibration_rms_px": res.reprojection_rms_px,
        "T_base_cam": res.T_base_cam.tolist(),
        "cloud_points": len(cloud),
        "cloud_counts": cloud.counts,
        "recorded_joints": recorded.tolist(),
        "recorded_state_valid": valid,
        "outputs": sorted(str(p) for p in out.iterdir() if p.suffix in (".yaml", ".png", ".ply")),
        "wall_s": time.perf_counter() - t0,
    }
    write_json(out / "summary.json", summary)
    print_table(
        [
            ("bag", str(SAMPLE_BAG)),
            (
                "calibration",
                f"RMS {res.reprojection_rms_px:.3f} px, "
                f"camera at {np.round(res.T_base_cam[:3, 3], 3).tolist()} m",
            ),
            (
                "scene cloud",
                f"{len(cloud):,} points (robot removed: {cloud.counts.get('robot_removed', 0):,})",
            ),
            (
                "recorded state",
                "collision-free in the cloud" if valid else "in collision with the cloud",
            ),
            ("outputs", str(out)),
            ("wall time", f"{summary['wall_s']:.1f} s"),
        ],
        "gaide demo",
    )
    return 0
