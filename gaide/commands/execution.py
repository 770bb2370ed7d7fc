"""``gaide time``, ``gaide simulate``, ``gaide compare`` and ``gaide bench timing``: a planned
path to a timed trajectory, its simulated execution, and a plan against a controller log."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from execution.ros2_goal import Ros2GoalCfg
from execution.sim_cfg import SimCfg
from execution.timing_cfg import TimingCfg, TimingMode, timing_phrase
from execution.urscript import UrScriptCfg, UrScriptMode, ur_order
from gaide.common import (
    add_checker_option,
    add_robot_option,
    print_table,
    progress,
    robot_and_spheres,
    write_json,
)
from gaide.pipeline.config import SimulateCfg
from gaide.scene_spec import HELP as SCENE_HELP
from gaide.scene_spec import Scene, load_scene, next_to
from gaide_core.errors import ConfigError, ExecutionError, TimingError
from gaide_core.plan_file import PlanFile, read_plan

# the defaults the flags show (gaide run's too)
# gaide simulate replays as gaide run simulates: its section's defaults (finer boxes, a crop)
TIMING, SIM, URSCRIPT, GOAL = TimingCfg(), SimulateCfg(), UrScriptCfg(), Ros2GoalCfg()


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    tm = sub.add_parser("time", help="a path (gaide plan's JSON) to a timed trajectory (Ruckig)")
    tm.add_argument(
        "path", help="path JSON written by `gaide plan` (keys path, joint_names, scene)"
    )
    tm.add_argument(
        "-o",
        "--output",
        action="append",
        required=True,
        help="trajectory file, repeatable; the suffix picks the format: .csv, .json, "
        ".bag (ROS1 JointTrajectory), a folder name without a suffix (ROS2 bag), .script "
        "(URScript program for a UR) or .yaml/.yml (ros2_control FollowJointTrajectory goal)",
    )
    tm.add_argument("--mode", choices=[m.value for m in TimingMode], default=TIMING.mode.value)
    tm.add_argument("--rate", type=float, default=TIMING.rate_hz, help="controller rate (Hz)")
    tm.add_argument("--scene", help=f"the path's scene (default: the file's 'scene'): {SCENE_HELP}")
    tm.add_argument("--plot", help="PNG of position, velocity, acceleration, jerk and limits")
    tm.add_argument("--storage", choices=["sqlite3", "mcap"], default="sqlite3", help="ROS2 bags")
    tm.add_argument(
        "--urscript-mode",
        choices=[m.value for m in UrScriptMode],
        default=URSCRIPT.urscript_mode.value,
        help=".script: servoj streams every sample, movej moves through the waypoints",
    )
    tm.add_argument(
        "--servoj-period",
        type=float,
        default=URSCRIPT.servoj_period_s,
        help=".script: servoj's t (s), whole 2 ms cycles, 0.008 for a CB3 (default: the "
        "trajectory's sample period)",
    )
    tm.add_argument(
        "--ros2-controller",
        default=GOAL.ros2_controller,
        help=".yaml: the goal's action is /ROS2_CONTROLLER/follow_joint_trajectory",
    )
    tm.add_argument(
        "--goal-rate",
        type=float,
        default=GOAL.goal_rate_hz,
        help=".yaml: points per second at most (every k-th sample)",
    )
    for kind, unit in (("velocity", "rad/s"), ("acceleration", "rad/s^2"), ("jerk", "rad/s^3")):
        tm.add_argument(
            f"--{kind}-scale",
            type=float,
            default=getattr(TIMING, f"{kind}_scale"),
            help=f"{kind} limits x this, in (0, 1]",
        )
        tm.add_argument(f"--max-{kind}", help=f"per-joint {kind} limits ({unit}), comma-separated")
    tm.add_argument("--no-shortcut", action="store_true", help="time the path as given")
    add_robot_option(tm)
    add_checker_option(tm)
    tm.set_defaults(func=cmd_time)

    sim = sub.add_parser("simulate", help="track a timed trajectory in PyBullet, log the states")
    sim.add_argument("trajectory", help="trajectory .csv/.json (gaide time), or a bag")
    sim.add_argument("--scene", default="none", help=f"obstacles: {SCENE_HELP}")
    sim.add_argument(
        "--log",
        action="append",
        default=[],
        help="joint-state log, repeatable: .csv, .bag (ROS1 JointState) or a folder (ROS2)",
    )
    sim.add_argument("--json", help="write the tracking report here")
    sim.add_argument("--plot", help="PNG of planned vs simulated positions and the error")
    sim.add_argument(
        "--settle", type=float, default=SIM.settle_s, help="hold the goal this long (s)"
    )
    sim.add_argument(
        "--voxel", type=float, default=SIM.voxel_m, help="a cloud's boxes: their size (m)"
    )
    sim.add_argument(
        "--crop",
        type=float,
        default=SIM.crop_m,
        help="a cloud's points farther than this from the moving robot's spheres are left "
        "out (m; 0: none)",
    )
    sim.add_argument("--storage", choices=["sqlite3", "mcap"], default="sqlite3", help="ROS2 bags")
    add_robot_option(sim)
    add_checker_option(sim)
    sim.set_defaults(func=cmd_simulate)

    cmp = sub.add_parser("compare", help="a planned trajectory against a controller log")
    cmp.add_argument("trajectory", help="trajectory .csv/.json (gaide time), or a bag")
    cmp.add_argument(
        "log", help="JointState log: a bag (ROS1/ROS2) or CSV (gaide's or `rostopic echo -p`)"
    )
    cmp.add_argument("--topic", help="JointState topic (default: the bag's only one)")
    cmp.add_argument(
        "--expected-start",
        type=float,
        default=0.0,
        help="s after the log's first sample where the plan should start (default 0)",
    )
    cmp.add_argument("--max-delay", type=float, help="search delays within +- this (s)")
    cmp.add_argument("--plot", help="PNG of plan vs log and the tracking error")
    cmp.add_argument("--json", help="write the comparison here")
    cmp.set_defaults(func=cmd_compare)


# -- gaide time ------------------------------------------------------------------------------


def _floats(text: str | None, what: str) -> tuple[float, ...] | None:
    if text is None:
        return None
    try:
        return tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError as err:
        raise ConfigError(f"--{what}: give comma-separated numbers, got '{text}'") from err


def _scene_for(
    args: argparse.Namespace, plan: PlanFile, source: str, robot: Any, spheres: Any
) -> Scene:
    if args.scene:
        return load_scene(args.scene, robot, spheres)
    if not plan.scene:
        raise TimingError(
            f"{source} names no scene (key 'scene'); give --scene ({SCENE_HELP}) so that "
            "the path can be checked and blends re-checked"
        )
    return load_scene(next_to(plan.scene, Path(source).parent), robot, spheres)


def cmd_time(args: argparse.Namespace) -> int:
    # The inputs first (the path file, the settings): a mistake there is said at once,
    # before the robot, Ruckig and the plots load.
    plan = read_plan(args.path)
    cfg = TimingCfg(
        rate_hz=args.rate,
        mode=TimingMode.parse(args.mode),
        velocity_scale=args.velocity_scale,
        acceleration_scale=args.acceleration_scale,
        jerk_scale=args.jerk_scale,
        max_velocity=_floats(args.max_velocity, "max-velocity"),
        max_acceleration=_floats(args.max_acceleration, "max-acceleration"),
        max_jerk=_floats(args.max_jerk, "max-jerk"),
        shortcut=not args.no_shortcut,
    )
    urscript = UrScriptCfg(urscript_mode=args.urscript_mode, servoj_period_s=args.servoj_period)
    goal = Ros2GoalCfg(ros2_controller=args.ros2_controller, goal_rate_hz=args.goal_rate)
    from execution.export import check_trajectory_outputs, write_trajectory
    from execution.plots import trajectory_png
    from execution.ruckig_timing import RuckigParameterizer
    from execution.verify import limit_violations
    from planning.checker import make_checker

    outputs = check_trajectory_outputs(args.output)
    robot, spheres = robot_and_spheres(args.robot)
    if any(p.suffix == ".script" for p in outputs):  # a UR's program: said before the timing
        ur_order(robot.joint_names)
    names = plan.joint_names
    if names is not None and names != tuple(robot.joint_names):
        raise TimingError(
            f"{args.path}: joint_names {list(names)} are not the robot's {list(robot.joint_names)}; "
            "give the robot config the path was planned for (--robot)"
        )
    scene = _scene_for(args, plan, args.path, robot, spheres)
    checker = make_checker(robot, spheres, scene.world, backend=args.checker)
    traj = RuckigParameterizer(cfg).parameterize(plan.path, checker)
    violations = limit_violations(traj)
    if violations:  # Ruckig keeps the limits by construction; this would be a bug
        raise TimingError(f"the trajectory breaks a limit at {violations} samples (1 kHz)")
    extra = {Path(args.plot): trajectory_png(traj)} if args.plot else {}
    written = write_trajectory(
        traj,
        args.output,
        storage=args.storage,
        extra=extra,
        urscript=urscript,
        goal=goal,
        robot=robot,
    )
    fig = traj.figures
    print_table(
        [
            ("mode", timing_phrase(cfg.mode.value, int(fig.get("fallbacks", 0)))),
            ("scene", scene.label),
            ("duration", f"{traj.duration:.3f} s, {len(traj.t)} samples at {cfg.rate_hz:g} Hz"),
            (
                "waypoints",
                f"{int(fig['input_waypoints'])} in, {int(fig.get('shortcut_waypoints', 0))} after "
                f"shortcutting, {len(traj.path) if traj.path is not None else 0} timed",
            ),
            (
                "path length",
                f"{fig['input_length_rad']:.3f} -> {fig['path_length_rad']:.3f} rad",
            ),
            ("blends", f"{sum(s.blended for s in traj.segments)} of {len(traj.segments)} segments"),
            ("limit violations", "0 (1 kHz re-sampling)"),
            ("time", f"{fig['ms_total']:.1f} ms ({fig['ms_recheck']:.1f} ms collision re-check)"),
            ("written", ", ".join(str(p) for p in [*written, *extra])),
        ],
        "timed trajectory",
    )
    for note in traj.notes:
        print(f"note: {note}")
    return 0


# -- gaide simulate / compare --------------------------------------------------------------


def _read_any_trajectory(path: str) -> Any:
    source = Path(path)
    if not source.exists():  # said before the readers (and Ruckig, rosbags) load
        raise ExecutionError(f"trajectory file {source} does not exist")
    if source.suffix in (".csv", ".json"):
        from execution.trajectory_io import read_trajectory

        return read_trajectory(source)
    if source.suffix in (".bag", ".mcap", "") or source.is_dir():
        from execution.ros_bags import read_trajectory_bag

        return read_trajectory_bag(source)
    raise ExecutionError(f"{source}: a trajectory is a .csv, .json or a bag")


def _per_joint_rows(
    names: tuple[str, ...], rms: np.ndarray, mx: np.ndarray
) -> list[tuple[str, str]]:
    return [
        (name, f"RMS {1e3 * r:7.3f} mrad   max {1e3 * m:7.3f} mrad")
        for name, r, m in zip(names, rms, mx, strict=True)
    ]


def cmd_simulate(args: argparse.Namespace) -> int:
    traj = _read_any_trajectory(args.trajectory)  # before the simulator and the robot load
    sim_cfg = SimCfg(settle_s=args.settle, voxel_m=args.voxel)
    if not 0.0 <= args.crop <= 10.0:
        raise ExecutionError(f"--crop must be in [0, 10] m, got {args.crop}")
    from execution.compare import compare
    from execution.export import check_joints, check_log_outputs, write_log
    from execution.plots import comparison_png
    from planning.checker import make_checker

    check_log_outputs(args.log)
    robot, spheres = robot_and_spheres(args.robot)
    # before PyBullet loads (its import prints a line) and the scene
    check_joints(traj.joint_names, robot, f"trajectory {args.trajectory}")
    from execution.simulate import cloud_near_motion, simulate

    scene = load_scene(args.scene, robot, spheres)
    checker = make_checker(robot, spheres, scene.world, backend=args.checker)
    cloud = scene.cloud
    if cloud is not None and args.crop > 0:
        cloud = cloud_near_motion(cloud, traj, checker, args.crop)
    result = simulate(
        traj,
        robot,
        primitives=scene.primitives,
        cloud=cloud if cloud is None or len(cloud) else None,
        cfg=sim_cfg,
        start_ns=time.time_ns(),
        checker=checker,
    )
    report = {"trajectory": args.trajectory, "scene": scene.label, **result.summary()}
    extra: dict[Path, bytes] = {}
    if args.json:
        extra[Path(args.json)] = (json.dumps(report, indent=2) + "\n").encode()
    if args.plot:
        extra[Path(args.plot)] = comparison_png(compare(traj, result.log))
    written = write_log(result.log, args.log, storage=args.storage, extra=extra)
    rows = _per_joint_rows(result.log.names, result.rms_rad, result.max_rad)
    rows.append(
        (
            "all joints",
            f"RMS {1e3 * result.rms_all_rad:7.3f} mrad   max {1e3 * result.max_all_rad:7.3f} mrad",
        )
    )
    if result.controller == "servo":
        rows.append(
            (
                "servo",
                f"{result.rate_hz:g} Hz, delay {1e3 * result.delay_s:.3g} ms; after it RMS "
                f"{1e3 * (result.rms_after_delay_all_rad or 0.0):.3f} mrad, max "
                f"{1e3 * (result.max_after_delay_all_rad or 0.0):.3f} mrad; "
                f"{result.limited_cycles} cycles limited, {result.saturated_cycles} saturated",
            )
        )
    if result.clearance_ok is not None:
        clear = result.executed_min_clearance_m
        finite = clear is not None and clear != float("inf")
        rows.append(
            (
                "executed clearance",
                (f"{1e3 * clear:.2f} mm" if finite and clear is not None else "no obstacles")
                + f" ({'>=' if result.clearance_ok else '<'} margin "
                f"{1e3 * (result.clearance_margin_m or 0.0):.1f} mm; "
                f"{result.executed_invalid} invalid configurations)",
            )
        )
    rows.append(("contacts", f"{len(result.contacts)} ({result.status.value})"))
    rows.append(
        (
            "sphere pre-check",
            "every sample valid"
            if not result.precheck_invalid
            else f"{result.precheck_invalid} invalid samples from {result.precheck_first_s:.3f} s",
        )
    )
    rows.append(("written", ", ".join(str(p) for p in [*written, *extra]) or "nothing"))
    print_table(rows, f"simulated {args.trajectory} in scene {scene.label} ({result.wall_s:.1f} s)")
    verdict = {True: "the URDF meshes hit too", False: "hull only: the URDF meshes clear it"}
    for c in result.contacts:
        print(
            f"contact: {c.link} with {c.obstacle} from {c.first_s:.3f} s to {c.last_s:.3f} s"
            + (f" ({verdict[c.mesh_confirmed]})" if c.mesh_confirmed is not None else "")
        )
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    if not Path(args.log).exists():  # said before the readers load
        raise ExecutionError(f"log file {args.log} does not exist")
    traj = _read_any_trajectory(args.trajectory)
    from execution.compare import CompareCfg, compare
    from execution.export import read_log
    from execution.plots import comparison_png
    from gaide_core.atomic import write_files_atomic

    log = read_log(args.log, args.topic)
    result = compare(
        traj, log, CompareCfg(expected_start_s=args.expected_start, max_delay_s=args.max_delay)
    )
    outputs: dict[Path, bytes] = {}
    if args.json:
        payload = {"trajectory": args.trajectory, "log": args.log, **result.summary()}
        outputs[Path(args.json)] = (json.dumps(payload, indent=2) + "\n").encode()
    if args.plot:
        outputs[Path(args.plot)] = comparison_png(result)
    write_files_atomic(list(outputs.items()), ExecutionError)
    rows = [
        (
            "delay",
            f"{1e3 * result.delay_s:.1f} ms (plan starts {result.start_s:.4f} s into the log)",
        ),
        ("overlap", f"{result.overlap_s:.3f} s, {len(result.t)} samples"),
        ("correlation", f"{result.correlation:.4f}"),
        *_per_joint_rows(result.joint_names, result.rms_rad, result.max_rad),
    ]
    if outputs:
        rows.append(("written", ", ".join(str(p) for p in outputs)))
    print_table(rows, f"{args.trajectory} vs {args.log}")
    return 0


# -- gaide bench timing --------------------------------------------------------------------


def add_bench_parser(bsub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """``gaide bench timing`` (registered by gaide.commands.bench)."""
    p = bsub.add_parser("timing", help="time parameterization on the harness's paths")
    p.add_argument("--paths", type=int, default=60, help="paths (spread over the families)")
    p.add_argument("--families", default="all", help="comma-separated families or 'all'")
    p.add_argument("--budget", type=float, default=5.0, help="RRT-Connect budget per path (s)")
    add_robot_option(p)
    p.add_argument("--json", help="write the figures to this JSON file")
    p.set_defaults(func=cmd_bench_timing)


def cmd_bench_timing(args: argparse.Namespace) -> int:
    from execution.bench_timing import TimingBenchCfg, run_timing_benchmark
    from planning.family_names import parse_families

    robot, spheres = robot_and_spheres(args.robot)
    cfg = TimingBenchCfg(
        paths=args.paths, families=tuple(parse_families(args.families)), budget_s=args.budget
    )
    res = run_timing_benchmark(robot, spheres, cfg, progress=progress)

    def fmt(key: str, spec: str, target: str) -> tuple[str, str]:
        value = res[key]
        return key, ("n/a" if value is None else format(value, spec)) + f"  (target {target})"

    print_table(
        [
            ("paths", f"{res['n_paths']} ({res['n_multi_segment']} with >= 3 segments)"),
            fmt("limit_violations", "d", "0"),
            fmt("exact_path_dev_rad", ".2e", "<= 1e-6"),
            fmt("blended_over_exact_duration", ".3f", "<= 0.8"),
            fmt("blended_collisions", "d", "0"),
            fmt("ms_per_path", ".1f", "<= 50"),
            fmt("sim_tracking_rms_rad", ".2e", "none: the servo model, its delay included"),
            fmt("sim_tracking_max_rad", ".2e", "none"),
            fmt("sim_delay_recovered_ms", ".3f", f"{res['sim_delay_configured_ms']} +- 1"),
            fmt("sim_clearance_violations", "d", "0"),
            ("wall time", f"{res['wall_s']:.1f} s"),
        ],
        "timing benchmark",
    )
    if args.json:
        write_json(args.json, res)
    return 0
