"""``gaide calibrate`` and ``gaide perceive``: camera-to-base calibration and the scene cloud."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gaide.common import add_robot_option, print_table, robot_and_spheres, write_json
from gaide_core.errors import ConfigError
from perception.cloud_cfg import CloudCfg

if TYPE_CHECKING:  # annotations only: the commands import their modules when they run
    from calibration.result import CalibrationResult


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    cal = sub.add_parser(
        "calibrate",
        help="camera-to-base transform from a tag or board, in a bag or in photos",
        description="Calibrate the camera to the robot: from a RealSense bag (color frames, "
        "joint states for hand-eye) or from photos (--images) with an intrinsics file and, for "
        "hand-eye, a flange pose per photo (--poses).",
    )
    cal.add_argument("bag", nargs="?", help="RealSense bag (ROS1 .bag, ROS2 folder or .mcap)")
    cal.add_argument("--images", help="photos instead of a bag: a folder or a glob ('cal/*.png')")
    cal.add_argument(
        "--intrinsics",
        help="with --images: ROS camera_info YAML, OpenCV YAML/XML or JSON (default: estimated "
        "from the same photos; needs a board target)",
    )
    cal.add_argument(
        "--poses",
        help="hand-eye with --images: flange pose per photo (YAML/CSV, xyz + quat_xyzw in m, "
        "or joint positions in rad with --robot), or a folder with one file per photo",
    )
    cal.add_argument("--mode", choices=["fixed", "hand-eye"], default="fixed")
    cal.add_argument(
        "--setup",
        choices=["eye-to-hand", "eye-in-hand"],
        default="eye-to-hand",
        help="hand-eye: camera fixed and target on the flange (eye-to-hand), or camera on the "
        "flange and target fixed (eye-in-hand)",
    )
    cal.add_argument(
        "--target",
        help="target spec, e.g. tag36h11:id=0,size=0.08, "
        "charuco:5x7,square=0.04,marker=0.03,dict=DICT_6X6_250 (hand-eye; overrides the pose "
        "file's)",
    )
    cal.add_argument(
        "--target-pose", help="fixed mode: YAML with the target and its pose in the base frame"
    )
    add_robot_option(cal, " (for hand-eye)")
    cal.add_argument("--flange", help="frame of the flange poses (hand-eye; default: end effector)")
    cal.add_argument("--base-frame", default="base_link", help="TF name of the robot base frame")
    cal.add_argument(
        "--camera-frame", default="camera_color_optical_frame", help="TF name of the camera frame"
    )
    cal.add_argument("--max-frames", type=int, help="use at most this many color frames (bags)")
    cal.add_argument("-o", "--output", required=True, help="calibration YAML to write")
    cal.add_argument("--overlay", help="overlay PNG (default: beside the YAML)")
    cal.add_argument(
        "--handeye-yaml",
        help="easy_handeye2/MoveIt-style YAML with the static TF line (default: beside the "
        "YAML, NAME.handeye.yaml)",
    )
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
    add_robot_option(per)
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
    from calibration.result import Setup
    from calibration.ros_export import Frames, save_handeye_yaml, static_transform_command
    from calibration.targets import parse_target
    from gaide.flows.calibrate import calibrate_bag, calibrate_images
    from gaide_core.errors import CalibrationError
    from planning.robot_model import load_robot

    if (args.bag is None) == (args.images is None):
        raise CalibrationError("give a bag or --images DIR|GLOB (one of them)")
    if args.bag is not None and (args.intrinsics or args.poses):
        raise CalibrationError("--intrinsics and --poses go with --images; a bag carries both")
    target = parse_target(args.target) if args.target else None
    setup = Setup.parse(args.setup)
    needs_robot = args.mode == "hand-eye" or args.robot is not None
    robot = load_robot(args.robot) if needs_robot else None
    intrinsics_rms = None
    if args.bag is not None:
        run = calibrate_bag(
            args.bag,
            mode=args.mode,
            robot=robot,
            target=target,
            target_pose=args.target_pose,
            flange=args.flange,
            max_frames=args.max_frames,
            setup=setup,
        )
        res, overlay_image = run.result, run.overlay
    else:
        photos = calibrate_images(
            args.images,
            mode=args.mode,
            intrinsics=args.intrinsics,
            poses=args.poses,
            robot=robot,
            target=target,
            target_pose=args.target_pose,
            flange=args.flange,
            setup=setup,
        )
        res, overlay_image, intrinsics_rms = (
            photos.result,
            photos.overlay,
            photos.intrinsics_rms_px,
        )
    out = Path(args.output)
    overlay = Path(args.overlay) if args.overlay else out.with_suffix(".overlay.png")
    handeye = Path(args.handeye_yaml) if args.handeye_yaml else out.with_suffix(".handeye.yaml")
    flange = args.flange or (robot.config.end_effector if robot is not None else "tool0")
    frames = Frames(args.base_frame, flange, args.camera_frame)
    written: list[Path] = []
    try:
        written.append(save_png(overlay, overlay_image))
        written.append(save_handeye_yaml(res, frames, handeye))
        res.save_yaml(out)
    except Exception:
        for path in written:
            path.unlink(missing_ok=True)
        raise
    rows = _calibration_rows(res, intrinsics_rms)
    rows += [("calibration", str(out)), ("hand-eye YAML", str(handeye)), ("overlay", str(overlay))]
    print_table(rows, "calibration")
    tf_line = static_transform_command(res, frames)
    print(tf_line)
    if args.json:
        figures = _calibration_figures(res, intrinsics_rms)
        figures.update(
            calibration=str(out),
            overlay=str(overlay),
            handeye_yaml=str(handeye),
            static_transform_publisher=tf_line,
        )
        write_json(args.json, figures)
    return 0


def _calibration_rows(
    res: CalibrationResult, intrinsics_rms: float | None
) -> list[tuple[str, str]]:
    """The summary table's rows for a calibration: mode, frames, error, the pose found, its
    standard deviation and the frames dropped."""
    from gaide_core.transforms import to_xyz_quat

    used = sum(f.used for f in res.frames)
    rows = [
        ("mode", res.mode.value + ("" if res.setup is None else f" ({res.setup.value})")),
        ("frames used", f"{used} of {len(res.frames)}"),
        ("reprojection RMS", f"{res.reprojection_rms_px:.3f} px"),
    ]
    if intrinsics_rms is not None:
        rows.append(("intrinsics", f"estimated from the photos, RMS {intrinsics_rms:.3f} px"))
    name, T = (
        ("T_flange_cam", res.T_flange_cam)
        if res.T_flange_cam is not None
        else ("T_base_cam", res.T_base_cam)
    )
    xyz, quat = to_xyz_quat(T)
    rows += [
        (f"{name} xyz", f"{np.round(xyz, 4).tolist()} m"),
        (f"{name} quat", f"{np.round(quat, 5).tolist()} (x, y, z, w)"),
    ]
    if res.uncertainty is not None:
        u = res.uncertainty
        rows.append(("standard deviation", f"{u.translation_mm:.2f} mm, {u.rotation_deg:.3f} deg"))
    for f in res.frames:
        if f.rms_px is not None and not f.used:
            rows.append((f"frame {f.index} dropped", f.reason))
    return rows


def _calibration_figures(res: CalibrationResult, intrinsics_rms: float | None) -> dict[str, object]:
    """``gaide calibrate --json``'s figures of a calibration (the files written are added by
    the caller)."""
    figures: dict[str, object] = {
        "reprojection_rms_px": res.reprojection_rms_px,
        "frames_used": sum(f.used for f in res.frames),
        "frames": len(res.frames),
        "T_base_cam": res.T_base_cam.tolist(),
        "frame_rms_px": [f.rms_px for f in res.frames],
    }
    if res.setup is not None:
        figures["setup"] = res.setup.value
    if res.T_flange_cam is not None:
        figures["T_flange_cam"] = res.T_flange_cam.tolist()
    if res.spread is not None:
        figures["spread_mm"] = res.spread.translation_mm
        figures["spread_deg"] = res.spread.rotation_deg
    if res.uncertainty is not None:
        figures["std_mm"] = res.uncertainty.translation_mm
        figures["std_deg"] = res.uncertainty.rotation_deg
    if intrinsics_rms is not None:
        figures["intrinsics_rms_px"] = intrinsics_rms
    return figures


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
