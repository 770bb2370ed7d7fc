"""``gaide calibrate`` and ``gaide perceive``: camera-to-base calibration and the scene cloud."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from gaide.common import print_table, robot_and_spheres, write_json
from gaide_core.errors import ConfigError
from perception.cloud_cfg import CloudCfg


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    cal = sub.add_parser("calibrate", help="camera-to-base transform from a tag or board in a bag")
    cal.add_argument("bag", help="RealSense bag (ROS1 .bag, ROS2 folder or .mcap)")
    cal.add_argument("--mode", choices=["fixed", "hand-eye"], default="fixed")
    cal.add_argument(
        "--target",
        help="target spec, e.g. tag36h11:id=0,size=0.08 or "
        "charuco:7x5,square=0.04,marker=0.03 (hand-eye; overrides the pose file's)",
    )
    cal.add_argument(
        "--target-pose", help="fixed mode: YAML with the target and its pose in the base frame"
    )
    cal.add_argument("--robot", help="robot config YAML (hand-eye; default: UR5)")
    cal.add_argument("--flange", help="frame carrying the target (hand-eye; default: end effector)")
    cal.add_argument("--max-frames", type=int, help="use at most this many color frames")
    cal.add_argument("-o", "--output", required=True, help="calibration YAML to write")
    cal.add_argument("--overlay", help="overlay PNG (default: beside the YAML)")
    cal.add_argument("--json", help="write the figures to this JSON file")
    cal.set_defaults(func=cmd_calibrate)

    per = sub.add_parser("perceive", help="the scene as a point cloud in the robot base frame")
    per.add_argument("bag", help="RealSense bag (ROS1 .bag, ROS2 folder or .mcap)")
    src = per.add_mutually_exclusive_group(required=True)
    src.add_argument("--calib", help="calibration YAML from 'gaide calibrate'")
    src.add_argument(
        "--T-base-cam",
        dest="T_base_cam",
        help="color camera pose in the base frame: x,y,z,qx,qy,qz,qw (m)",
    )
    per.add_argument("--robot", help="robot config YAML (default: UR5)")
    per.add_argument(
        "--joints", help="robot joint values (rad, comma separated) when the bag has none"
    )
    per.add_argument("--no-self-filter", action="store_true", help="keep the robot's own points")
    per.add_argument(
        "--default-extrinsics",
        action="store_true",
        help="a bag without depth-to-color extrinsics: assume the identity (~15 mm off on a "
        "D400) instead of refusing it",
    )
    per.add_argument("--voxel", type=float, default=CloudCfg().voxel, help="downsampling voxel (m)")
    per.add_argument(
        "--workspace", help="crop box in the base frame: xmin,ymin,zmin,xmax,ymax,zmax (m)"
    )
    per.add_argument("-o", "--output", required=True, help="PLY file to write")
    per.add_argument("--png", help="picture of the cloud (default: beside the PLY)")
    per.add_argument("--json", help="write the figures to this JSON file")
    per.set_defaults(func=cmd_perceive)


def _floats(text: str, n: int, what: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as err:
        raise ConfigError(f"{what} must be {n} comma-separated numbers, got '{text}'") from err
    if len(values) != n:
        raise ConfigError(f"{what} must be {n} comma-separated numbers, got {len(values)}")
    return values


def cmd_calibrate(args: argparse.Namespace) -> int:
    from calibration.overlay import save_png
    from calibration.targets import parse_target
    from gaide.flows.calibrate import calibrate_bag
    from gaide_core.transforms import to_xyz_quat
    from planning.robot_model import load_robot

    target = parse_target(args.target) if args.target else None
    robot = load_robot(args.robot) if args.mode == "hand-eye" else None
    run = calibrate_bag(
        args.bag,
        mode=args.mode,
        robot=robot,
        target=target,
        target_pose=args.target_pose,
        flange=args.flange,
        max_frames=args.max_frames,
    )
    out = Path(args.output)
    overlay = Path(args.overlay) if args.overlay else out.with_suffix(".overlay.png")
    save_png(overlay, run.overlay)
    try:
        run.result.save_yaml(out)
    except Exception:
        overlay.unlink(missing_ok=True)
        raise
    res = run.result
    used = sum(f.used for f in res.frames)
    xyz, quat = to_xyz_quat(res.T_base_cam)
    rows = [
        ("mode", res.mode.value if hasattr(res.mode, "value") else str(res.mode)),
        ("frames used", f"{used} of {len(res.frames)}"),
        ("reprojection RMS", f"{res.reprojection_rms_px:.3f} px"),
        ("T_base_cam xyz", f"{np.round(xyz, 4).tolist()} m"),
        ("T_base_cam quat", f"{np.round(quat, 5).tolist()} (x, y, z, w)"),
    ]
    if res.spread is not None:
        rows.append(
            (
                "methods' spread",
                f"{res.spread.translation_mm:.2f} mm, {res.spread.rotation_deg:.3f} deg",
            )
        )
    rows += [("calibration", str(out)), ("overlay", str(overlay))]
    print_table(rows, "calibration")
    if args.json:
        figures = {
            "reprojection_rms_px": res.reprojection_rms_px,
            "frames_used": used,
            "frames": len(res.frames),
            "T_base_cam": res.T_base_cam.tolist(),
            "calibration": str(out),
            "overlay": str(overlay),
        }
        if res.spread is not None:
            figures["spread_mm"] = res.spread.translation_mm
            figures["spread_deg"] = res.spread.rotation_deg
        write_json(args.json, figures)
    return 0


def cmd_perceive(args: argparse.Namespace) -> int:
    from gaide.flows.perceive import perceive_bag
    from gaide_core.transforms import from_xyz_quat
    from perception.cloud import save_ply
    from perception.render import render_png

    robot, spheres = robot_and_spheres(args.robot)
    calibration: str | np.ndarray
    if args.calib:
        calibration = args.calib
    else:
        v = _floats(args.T_base_cam, 7, "--T-base-cam")
        calibration = from_xyz_quat(v[:3], v[3:])
    cfg_kwargs: dict[str, object] = {"voxel": args.voxel}
    if args.workspace:
        box = _floats(args.workspace, 6, "--workspace")
        cfg_kwargs.update(workspace_min=tuple(box[:3]), workspace_max=tuple(box[3:]))
    joints = np.asarray(_floats(args.joints, robot.dof, "--joints")) if args.joints else None
    cloud, _, q = perceive_bag(
        args.bag,
        calibration,
        robot,
        spheres,
        CloudCfg(**cfg_kwargs),  # type: ignore[arg-type]
        joints=joints,
        self_filter=not args.no_self_filter,
        default_extrinsics=args.default_extrinsics,
    )
    out = Path(args.output)
    png = Path(args.png) if args.png else out.with_suffix(".png")
    save_ply(str(out), cloud)
    try:
        render_png(png, cloud.points, cloud.colors)
    except Exception:
        out.unlink(missing_ok=True)
        raise
    rows = [(step, f"{n:,} points") for step, n in cloud.counts.items()]
    rows += [
        (
            "self-filter",
            "at recorded joints" if q is not None and not args.no_self_filter else "off",
        ),
        ("time", f"{cloud.seconds:.2f} s"),
        ("cloud", str(out)),
        ("picture", str(png)),
    ]
    print_table(rows, "scene cloud (base frame)")
    if args.json:
        write_json(
            args.json,
            {
                "points": len(cloud),
                "counts": cloud.counts,
                "seconds": cloud.seconds,
                "self_filter_joints": None if q is None else q.tolist(),
                "cloud": str(out),
                "picture": str(png),
            },
        )
    return 0
