"""``gaide record-synthetic``: render a synthetic workcell into a RealSense-layout bag."""

from __future__ import annotations

import argparse

import numpy as np

from gaide.common import add_robot_option, progress, robot_and_spheres, seed
from perception.frames import BagLayout


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "record-synthetic",
        help="render a known workcell into a RealSense bag with ground truth beside it",
    )
    p.add_argument(
        "-o", "--output", required=True, help="bag path (.bag for ROS1, a folder for ROS2)"
    )
    p.add_argument(
        "--mode",
        choices=["fixed", "hand-eye"],
        default="fixed",
        help="fixed: a board on the table; hand-eye: a board on the flange",
    )
    p.add_argument("--layout", choices=[m.value for m in BagLayout], default=BagLayout.SDK.value)
    p.add_argument("--ros", type=int, choices=[1, 2], default=1, help="ROS version of the bag")
    p.add_argument("--storage", choices=["sqlite3", "mcap"], default="sqlite3", help="ROS2 storage")
    p.add_argument("--frames", type=int, default=5, help="frames (fixed) or robot poses (hand-eye)")
    add_robot_option(p)
    p.add_argument("--seed", type=seed, default=0)
    p.set_defaults(func=cmd_record)


def cmd_record(args: argparse.Namespace) -> int:
    from gaide.synthetic.record import record_scene
    from gaide.synthetic.scene import fixed_scene, hand_eye_scene
    from planning.checker import make_checker

    robot, spheres = robot_and_spheres(args.robot)
    rng = np.random.default_rng(args.seed)
    if args.frames < 1:
        from gaide_core.errors import ConfigError

        raise ConfigError(f"--frames must be >= 1, got {args.frames}")
    if args.mode == "fixed":
        scene = fixed_scene(robot, rng, frames=args.frames)
    else:
        scene = hand_eye_scene(
            robot,
            lambda world: make_checker(robot, spheres, world),
            rng,
            states=args.frames,
        )
    bag, truth = record_scene(
        scene,
        robot,
        args.output,
        rng,
        layout=BagLayout(args.layout),
        ros_version=args.ros,
        storage=args.storage,
        progress=progress,
    )
    print(f"bag: {bag}\nground truth: {truth}")
    return 0
